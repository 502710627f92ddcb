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
#include "nodes/monitor.hpp"
#include "rig/fault_rig.hpp"
#include "rig/virtual_rig.hpp"

namespace pamc::app {
namespace {

// pamc monitor: a passive live view of the bus (or of a log), decoded through the EDS files.
class MonitorCommand final : public Command {
 public:
  explicit MonitorCommand(CLI::App& app)
      : Command(app.add_subcommand("monitor", "passive live view of a bus decoded through the EDS files")) {
    iface_.add(cmd_);
    cmd_->add_option("--replay", log_in, "replay a candump log instead of listening");
    addOldSpelling(cmd_, "--log", "--replay", log_in);
    od_.add(cmd_);
    dict_.add(cmd_);
    cmd_->add_option("--duration", duration, "stop after this many seconds (0: until Ctrl-C)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd_->add_flag("--once", once, "print one screen at the end and exit");
  }
  int run() override {
    auto dict = dict_.load(od_);
    nodes::Monitor mon(dict);
    if (!log_in.empty()) {
      std::vector<std::string> warnings;
      const auto log = canopen::readCandumpLog(log_in, &warnings);
      printWarnings(warnings);
      if (log.empty()) throw std::runtime_error(log_in + ": no frames");
      const double t0 = log.front().unix_time_us * 1e-6;
      double next = 0.5;
      for (const auto& r : log) {
        const double t = r.unix_time_us * 1e-6 - t0;
        if (!once && t >= next) {
          std::printf("\033[H\033[2J%s", mon.render(t).c_str());
          next += 0.5;
        }
        mon.feed(r.frame, t);
      }
      std::printf("%s%s", once ? "" : "\033[H\033[2J", mon.render(log.back().unix_time_us * 1e-6 - t0).c_str());
      return 0;
    }
    auto canp = openCan(iface_.resolve(dict_.rig));  // listen only: the monitor never sends
    auto& can = *canp;
    installSignals();
    const double t0 = canopen::monotonicNowUs() * 1e-6;
    double next = 0.5;
    canopen::Frame f;
    canopen::TimeUs ts;
    while (!g_stop) {
      bool any = false;
      while (can.receive(f, ts)) {
        mon.feed(f, canopen::monotonicNowUs() * 1e-6 - t0);
        any = true;
      }
      const double now = canopen::monotonicNowUs() * 1e-6 - t0;
      if (now >= next) {
        std::printf("\033[H\033[2J%s", mon.render(now).c_str());
        std::fflush(stdout);
        next += 0.5;
        if (once || (duration > 0 && now >= duration)) break;
      }
      if (!any) std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    return 0;
  }

 private:
  std::string log_in;
  InterfaceOption iface_;
  BusDictionaryOptions dict_;
  double duration = 0.0;  // live: until Ctrl-C
  bool once = false;
  OdOption od_;
};

}  // namespace

std::unique_ptr<Command> makeMonitorCommand(CLI::App& app) { return std::make_unique<MonitorCommand>(app); }

}  // namespace pamc::app
