#include "app/command.hpp"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "app/bus_common.hpp"
#include "app/controller_options.hpp"
#include "app/node_options.hpp"
#include "io/measurement.hpp"
#include "nodes/decoder.hpp"
#include "nodes/fault_report.hpp"
#include "nodes/master_dcf.hpp"
#include "nodes/monitor.hpp"
#include "rig/fault_rig.hpp"
#include "rig/virtual_rig.hpp"

namespace pamc::app {
namespace {

// pamc controller: the controller node on a SocketCAN interface.
class ControllerCommand final : public Command {
 public:
  explicit ControllerCommand(CLI::App& app)
      : Command(app.add_subcommand("controller", "run the controller node on a SocketCAN interface")) {
    iface_.add(cmd_);
    od_.add(cmd_);
    rig_.add(cmd_);
    cmd_->add_option(
        "--dcf", dcf_,
        "master DCF (CiA 306, docs/RIG.md): its values replace the controller EDS's defaults "
        "on top of the rig file's - the slaves' boot (0x1F22 concise DCFs, 0x1F81, 0x1F84-0x1F89), 0x1016, "
        "the PDOs; its NodeID is the controller's");
    kind_.add(cmd_);
    ctrl_.add(cmd_);
    run_.add(cmd_);
    cmd_->add_flag("--consume-sync", consume_sync, "another master produces SYNC");
    cmd_->add_option("--log", candump, "write every frame to this file as a candump -l log");
    rt_.add(cmd_, "real time");
  }
  int run() override {
    const std::string& csv = run_.csv;
    const double duration = run_.duration;
    if (!rig_.given()) rig_.path = od_.dir + "/rigs/default.ini";  // pamc's own rig, booted like any other
    auto c = controllerNodeConfig(od_, kind_, ctrl_, run_, consume_sync, &rig_);
    if (!dcf_.empty()) nodes::applyMasterDcf(dcf_, c);
    c.build_off_cycle = true;  // an SDO commit must not hold up the cycles of this thread
    const std::string iface = iface_.resolve(rig_.path);
    realtimeSetup(rt_.rt, rt_.cpu, rt_.priority);
    auto canp = openCan(iface);
    auto& can = *canp;
    // On the heap: the record rings are megabytes.
    auto nodep = std::make_unique<nodes::ControllerNode>(c, can, [] { return canopen::monotonicNowUs(); });
    auto& node = *nodep;
    auto loggerp = std::make_unique<Logger>(candump, iface, csv, c.period_us, c.channels.size());
    auto& logger = *loggerp;
    logger.records = &node.records();
    MeasurementRecord measurement(c.channels[0].layout.feedback, c.delay_cycles);
    attachMeasurement(logger, measurement, run_);
    // Every frame on the bus (received, and sent by this node) is logged and counted for the bus load.
    BusLoad load(rig_.given() ? readRig(rig_.path).bitrate : 1000000u);
    can.setTap([&](const canopen::Frame& f, canopen::TimeUs t, bool) {
      logger.frames.push({f, t});
      load.add(f, t);
    });
    canopen::EventLoop loop(can, node.node());
    g_loop = &loop;
    installSignals();
    logger.start();
    std::fprintf(stderr, "controller node %u on %s: %s, %s%s\n", node.node().nodeId(), iface.c_str(),
                 control::toString(node.kind()), c.trajectory.describe().c_str(),
                 c.produce_sync ? ", producing SYNC" : ", consuming SYNC");
    // --duration by the wall clock too: the run ends on time whatever the slaves do.
    const nodes::RunEnd end(duration, c.preroll_s, canopen::monotonicNowUs());
    std::thread watch([&] {
      nodes::FaultReporter reporter([](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); });
      while (!g_stop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        reporter.step(node);
        if (end.reached(node, canopen::monotonicNowUs())) loop.stop();
      }
    });
    {
      Joiner j{watch};
      node.start(canopen::monotonicNowUs());
      loop.run();
    }
    g_loop = nullptr;
    logger.stop();
    printStats(node.stats(), logger.summary);
    printJoints(readRig(rig_.path).joints, logger.summary);
    load.print();
    const auto& st = can.stats();
    std::printf("socket: rx %llu, tx %llu, tx queued %llu, tx dropped %llu, tx expired %llu, error frames %llu\n",
                static_cast<unsigned long long>(st.rx_frames), static_cast<unsigned long long>(st.tx_frames),
                static_cast<unsigned long long>(st.tx_queued), static_cast<unsigned long long>(st.tx_dropped),
                static_cast<unsigned long long>(st.tx_expired), static_cast<unsigned long long>(st.error_frames));
    if (auto why = nodes::runFailure(node)) throw std::runtime_error(*why);
    writeMeasurement(measurement, run_.out);
    return 0;
  }

 private:
  std::string candump, dcf_;
  InterfaceOption iface_;
  bool consume_sync = false;
  OdOption od_;
  RigOption rig_;
  ControllerKindOption kind_;
  ControllerOptions ctrl_;
  NodeRunOptions run_;
  RealtimeOptions rt_;
};

}  // namespace

std::unique_ptr<Command> makeControllerCommand(CLI::App& app) { return std::make_unique<ControllerCommand>(app); }

}  // namespace pamc::app
