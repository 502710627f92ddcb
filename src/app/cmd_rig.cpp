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
#include "io/text.hpp"
#include "nodes/decoder.hpp"
#include "nodes/monitor.hpp"
#include "app/run_figure.hpp"
#include "rig/rig_emulator.hpp"
#include "rig/fault_rig.hpp"
#include "rig/virtual_rig.hpp"

namespace pamc::app {
namespace {

// pamc rig run|faults|soak|guards: the controller and emulator nodes on the in-process bus (virtual time,
// or paced to the wall clock with --realtime), and the fault tools. The old flag forms (`pamc rig
// --faults`, `--soak H`, `--sdo-guards`, plain `pamc rig`) are hidden options of `rig` itself until 0.3.0.
class RigCommand final : public Command {
 public:
  explicit RigCommand(CLI::App& app)
      : Command(app.add_subcommand("rig",
                                   "controller and emulator as CANopen nodes on the in-process bus (no CAN "
                                   "hardware): a run, the fault table, the soak, the SDO guards")) {
    cmd_->require_subcommand(0, 1);
    run_cmd_ = cmd_->add_subcommand("run",
                                    "run the controller and the emulator through the CANopen layer, in "
                                    "virtual time (as fast as it goes) or paced to the wall clock (--realtime)");
    faults_cmd_ = cmd_->add_subcommand("faults",
                                       "run each fault on the bus (seeded) and print the fault table: "
                                       "reaction, cycles to the safe valve value, EMCY, recovery, data lost");
    soak_cmd_ = cmd_->add_subcommand("soak", soakHelp());
    guards_cmd_ = cmd_->add_subcommand("guards",
                                       "write parameters over SDO to the running controller and print "
                                       "the abort codes and what the loop saw");
    addRunOptions(run_cmd_);
    addFaultToolOptions(faults_cmd_, rig::FaultRigOptions{});
    faults_cmd_->add_option("--only", ft_.only, kOnlyHelp);
    addChannelOptions(faults_cmd_);
    addFaultToolOptions(soak_cmd_, rig::SoakOptions{});
    addSoakOptions(soak_cmd_);
    soak_cmd_->get_option("--hours")->required();
    addFaultToolOptions(guards_cmd_, rig::FaultRigOptions{});
    addOldForms();
    cmd_->callback([this] { noticeOfPlainRig(); });
  }
  int run() override {
    from_ = selectedApp();
    if (from_ == soak_cmd_ || (from_ == cmd_ && ft_.soak_hours > 0)) return runSoak();
    if (from_ == faults_cmd_ || from_ == guards_cmd_ || (from_ == cmd_ && (ft_.faults || ft_.sdo_guards)))
      return runRigChecks();
    const auto c = controllerNodeConfig(od_, kind_, ctrl_, run_, false, &rig_);
    ec = emu_.config(od_.dir, run_.period_us);
    bitrate_ = 1000000;
    if (rig_.given()) {
      const auto rf = readRig(rig_.path);
      ec = rig::emulatorOf(rf, ec);
      bitrate_ = rf.bitrate;
      joints_ = rf.joints;
    }
    if (rt_.rt) return runRigRealtime(c);
    return runVirtual(c);
  }

 private:
  static constexpr const char* kOnlyHelp = "comma list of faults, e.g. sync-stop,bus-off (an unknown name lists them)";
  static std::string soakHelp() {
    return "--hours of 1 kHz cycles in virtual time (the tool's own controller and gains unless --controller, --kp, "
           "--ki, "
           "--kc are given; a 0.2 Hz sine; the controller consuming the SYNC of a producer node, 1 Mbit/s bus) with "
           "faults of the catalogue injected one after the other at random times; prints per report interval the "
           "cycles, SYNC gaps, faults, tracking after each fault against the no-fault baseline, heap and RSS, CPU per "
           "cycle; exit 1 if memory grew, a cycle was lost outside a fault, tracking did not come back or left its "
           "level between faults, or CPU per cycle drifted";
  }
  void addRunOptions(CLI::App* a) {
    od_.add(a);
    rig_.add(a);
    kind_.add(a);
    ctrl_.add(a);
    run_.add(a);
    emu_.add(a);
    a->add_option("--log", candump, "write every frame to this file as a candump -l log");
    a->add_option("--figure", figure_,
                  "draw the run into this PNG: each joint's angle, each channel's position and "
                  "command against its setpoint (gnuplot; the data beside it as FILE.csv)");
    rt_.add(a,
            "pace the rig to the wall clock (1 ms of bus time per ms) like a live node: --log and --csv "
            "(t,yd,y,u,u_n,u_c,y_hat,fault,latency_us) are streamed by a logger thread and on disk within a "
            "millisecond, the log's times are wall-clock times",
            "rig run");
    a->add_option("--progress", progress,
                  "with --realtime: append 'cycle K t T bus_us B' to this file as each "
                  "cycle is computed (a marker for crash tests and watchdogs)");
  }
  // The fault tools take the controller and its gains from the command line (their own otherwise).
  template <class Own>
  void addFaultToolOptions(CLI::App* a, const Own& own) {
    od_.add(a);
    kind_.add(a);
    ctrl_.addGains(a);
    a->footer("Without --controller, --kp, --ki, --kc: the tool's own " + std::string(control::toString(own.kind)) +
              " with kp " + io::fmt("%g", own.kp) + ", ki " + io::fmt("%g", own.ki) + ", kc " + io::fmt("%g", own.kc) +
              " (each option given replaces its own).");
  }
  // rig faults on a rig file of several channels, the faults of the sensor on one channel's.
  void addChannelOptions(CLI::App* a) {
    a->add_option("--rig", ft_.rig,
                  "rig file of one to eight channels (docs/RIG.md, e.g. od/rigs/four_muscles.ini) to run the table "
                  "on, its devices played by the emulator; adds the channels the EMCYs named and what the other "
                  "channels did (without it: the built-in one-muscle rig)");
    a->add_option("--channel", ft_.channel,
                  "with --rig: the channel (1-based) whose sensor the faults of the sensor hit; the faults of the "
                  "valve module, the SYNC and the bus hit what every channel shares")
        ->capture_default_str();
  }
  void addSoakOptions(CLI::App* a) {
    a->add_option("--hours", ft_.soak_hours, "hours of cycles in virtual time")->check(CLI::PositiveNumber);
    a->add_option("--only", ft_.only, kOnlyHelp);
    a->add_option("--seed", ft_.seed, "seed of the fault times, fault choices and sensor noise")->capture_default_str();
    a->add_option("--report-every", ft_.report_every, "simulated seconds per report line")
        ->capture_default_str()
        ->check(CLI::Range(1.0, 1e6));
  }
  // The forms before the subcommands, on `rig` itself: every option of `rig run`, --faults, --sdo-guards,
  // --soak HOURS and their --only, --seed, --report-every; hidden from --help.
  void addOldForms() {
    addRunOptions(cmd_);
    addOldFlag(cmd_, "--faults", "rig faults", ft_.faults);
    addOldFlag(cmd_, "--sdo-guards", "rig guards", ft_.sdo_guards);
    addOldSpelling(cmd_, "--soak", "soak --hours", ft_.soak_hours);
    cmd_->add_option("--only", ft_.only);
    cmd_->add_option("--seed", ft_.seed);
    cmd_->add_option("--report-every", ft_.report_every);
    for (auto* o : cmd_->get_options())
      if (o->get_name() != "--help") o->group("");
  }
  CLI::App* selectedApp() const {
    for (auto* a : {run_cmd_, faults_cmd_, soak_cmd_, guards_cmd_})
      if (a->parsed()) return a;
    return cmd_;
  }
  // Plain `pamc rig [options]`, once parsed (the old flags name themselves when given).
  void noticeOfPlainRig() const {
    if (selectedApp() == cmd_ && oldSpellingNotices() == 0) oldSpellingNotice("rig", "rig run");
  }

  // The fault tools with the controller and gains the command line gives (the tools' own otherwise).
  template <class Options>
  void applyController(Options& o) const {
    if (from_->count("--controller")) o.kind = kind_.kind();
    if (from_->count("--kp")) o.kp = ctrl_.cc.kp;
    if (from_->count("--ki")) o.ki = ctrl_.cc.ki;
    if (from_->count("--kc")) o.kc = ctrl_.cc.kc;
  }
  std::vector<rig::BusFault> faultList() const {
    std::vector<rig::BusFault> list;
    std::string rest = ft_.only;
    while (!rest.empty()) {
      const auto c = rest.find(',');
      const std::string name = rest.substr(0, c);
      rest = c == std::string::npos ? "" : rest.substr(c + 1);
      bool found = false;
      for (auto f : rig::allBusFaults())
        if (name == rig::busFaultName(f)) list.push_back(f), found = true;
      if (!found) {
        std::string names;
        for (auto f : rig::allBusFaults()) names += std::string(names.empty() ? "" : ", ") + rig::busFaultName(f);
        throw std::invalid_argument("--only: unknown fault '" + name + "' (one of: " + names + ")");
      }
    }
    return list;
  }

  // --rig and --channel into o: the rig file read, the channel one of its own.
  void applyChannel(rig::FaultRigOptions& o) const {
    int channels = 1;
    if (!ft_.rig.empty()) {
      o.rig = readRig(ft_.rig);
      channels = static_cast<int>(o.rig->channels.size());
    }
    if (ft_.channel >= 1 && ft_.channel <= channels) {
      o.channel = static_cast<std::size_t>(ft_.channel - 1);
      return;
    }
    const std::string what = ft_.rig.empty() ? "the built-in rig" : ft_.rig;
    const std::string has =
        channels == 1 ? "one channel (1)" : std::to_string(channels) + " channels (1-" + std::to_string(channels) + ")";
    throw std::invalid_argument("--channel " + std::to_string(ft_.channel) + ": " + what + " has " + has);
  }

  int runRigChecks() {
    rig::FaultRigOptions o;
    o.od_dir = od_.dir;
    applyController(o);
    if (from_ == faults_cmd_) applyChannel(o);
    if (from_ == guards_cmd_ || ft_.sdo_guards) {
      std::printf("%s", rig::guardTableMarkdown(rig::runParameterGuards(o)).c_str());
      if (from_ == guards_cmd_ || !ft_.faults) return 0;
      std::printf("\n");
    }
    const auto list = faultList();
    std::fprintf(stderr,
                 "in-process bus, %s, fault injected after %g s of a 0.2 Hz sine, run on %g s after it cleared\n",
                 control::toString(o.kind), o.inject_at_s, o.after_s);
    if (o.rig)
      std::fprintf(stderr, "%s: %zu channel%s; the sensor is channel %zu's (node-ID %u)\n", ft_.rig.c_str(),
                   o.rig->channels.size(), o.rig->channels.size() == 1 ? "" : "s", o.channel + 1,
                   o.rig->channels[o.channel].cfg.sensor_id);
    std::printf("%s", rig::faultTableMarkdown(rig::runFaultTable(list, o)).c_str());
    return 0;
  }

  int runSoak() {
    rig::SoakOptions o;
    o.od_dir = od_.dir;
    o.hours = ft_.soak_hours;
    o.seed = ft_.seed;
    o.report_s = ft_.report_every;
    o.faults = faultList();
    // The fault table's controller and gains unless given.
    applyController(o);
    std::fprintf(stderr,
                 "soak: %g h of 1 kHz cycles in virtual time, %s (kp %g, ki %g, kc %g), 0.2 Hz sine 10-20 mm; "
                 "controller consuming the SYNC of a producer node, 1 Mbit/s bus; faults (%zu kinds) every %g-%g s "
                 "after the last check, seed %llu\n",
                 o.hours, control::toString(o.kind), o.kp, o.ki, o.kc,
                 o.faults.empty() ? rig::allBusFaults().size() : o.faults.size(), o.gap_min_s, o.gap_max_s,
                 static_cast<unsigned long long>(o.seed));
    std::printf("%s", rig::soakIntervalHeader().c_str());
    std::fflush(stdout);
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = rig::runSoak(
        o,
        [](const rig::SoakInterval& i) {
          std::printf("%s", rig::soakIntervalLine(i).c_str());
          std::fflush(stdout);
        },
        [&](double sim_s) {
          if (std::fmod(sim_s, 600.0) > 1.0) return;  // every 10 simulated minutes
          const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          const double total = o.hours * 3600.0;
          std::fprintf(stderr, "soak: %.2f of %g h simulated, %.0f s wall, about %.0f s to go\n", sim_s / 3600.0,
                       o.hours, wall, wall / sim_s * (total - sim_s));
        });
    std::printf("%s", rig::soakReport(o, r, false).c_str());  // the intervals are printed above
    return r.passed() ? 0 : 1;
  }

  int runRigRealtime(const nodes::ControllerNodeConfig& c) {
    auto ring = std::make_unique<nodes::SpscRing<nodes::CycleRecord, 1 << 15>>();
    auto loggerp = std::make_unique<Logger>(candump, kInProcessBusName, run_.csv, run_.period_us, c.channels.size());
    auto& logger = *loggerp;
    logger.records = ring.get();
    MeasurementRecord measurement(c.channels[0].layout.feedback, c.delay_cycles);
    attachMeasurement(logger, measurement, run_);
    int progress_fd = -1;
    if (!progress.empty()) {
      progress_fd = ::open(progress.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
      if (progress_fd < 0) throw std::runtime_error(progress + ": cannot write");
    }
    timespec wall{};
    ::clock_gettime(CLOCK_REALTIME, &wall);
    const canopen::TimeUs epoch = static_cast<canopen::TimeUs>(wall.tv_sec) * 1000000 + wall.tv_nsec / 1000;
    rig::VirtualRigHooks hooks;
    hooks.realtime = true;
    BusLoad load(bitrate_);
    hooks.tap = [&](const canopen::Frame& f, canopen::TimeUs t) {
      logger.frames.push({f, epoch + t});
      load.add(f, t);
    };
    nodes::CycleRecord last{};
    bool fresh = false;
    hooks.on_record = [&](const nodes::CycleRecord& r) {
      ring->push(r);
      last = r;
      fresh = true;
    };
    hooks.on_step = [&](canopen::TimeUs now) {
      if (progress_fd >= 0 && fresh) {
        // What the rig has computed so far (the logger may not have written it yet): the cycle, its
        // trajectory time and the bus time (the log's time stamps count from the first frame at bus time 0).
        char b[96];
        const int n =
            std::snprintf(b, sizeof b, "cycle %u t %.3f bus_us %lld\n", last.k, last.t, static_cast<long long>(now));
        if (::write(progress_fd, b, static_cast<size_t>(n)) < 0) progress_fd = -1;
        fresh = false;
      }
      return !g_stop.load();
    };
    installSignals();
    realtimeSetup(true, rt_.cpu, rt_.priority);
    logger.start();
    std::fprintf(
        stderr,
        "in-process bus paced in real time: controller (node %u) + sensor (%u) + valve (%u), %g s pre-roll + %s\n",
        c.node_id ? c.node_id : 1u, c.channels[0].sensor_id, c.channels[0].valve_id, run_.preroll,
        run_.duration > 0 ? (std::to_string(run_.duration) + " s run").c_str() : "run until stopped");
    const auto r = rig::runVirtualRig(c, ec, run_.duration, "", epoch, 0, hooks);
    logger.stop();
    if (progress_fd >= 0) ::close(progress_fd);
    std::printf("%llu frames on the bus, %llu faults%s%s\n", static_cast<unsigned long long>(r.frames),
                static_cast<unsigned long long>(r.faults), r.final_fault == nodes::Fault::None ? "" : ", last: ",
                r.final_fault == nodes::Fault::None ? "" : nodes::toString(r.final_fault));
    printStats(r.stats, logger.summary);
    printJoints(joints_, logger.summary);
    load.print();
    // In-process the SYNC period is exact in bus time; what real time costs is the pacing: how late
    // each 1 ms wake-up came (the node's work runs right after it).
    const auto& w = r.wake_late_us;
    std::printf(
        "wake-up lateness (%s): median %.1f us, p99 %.1f us, max %.1f us; %llu of %llu wake-ups a period or more "
        "late\n",
        rt_.priority > 0 ? ("SCHED_FIFO " + std::to_string(rt_.priority) + ", mlockall").c_str() : "normal scheduling",
        w.quantile(0.5), w.quantile(0.99), w.max(), static_cast<unsigned long long>(r.wake_overruns),
        static_cast<unsigned long long>(w.count()));
    writeMeasurement(measurement, run_.out);
    return 0;
  }

  // Virtual time, as fast as it goes; --duration 0 runs until Ctrl-C.
  int runVirtual(const nodes::ControllerNodeConfig& c) {
    rig::VirtualRigHooks hooks;
    const bool forever = run_.duration <= 0;
    if (forever) {
      installSignals();
      hooks.until_stopped = true;
      hooks.on_step = [](canopen::TimeUs) { return !g_stop.load(); };
    }
    // Records are kept only for --csv and --out (a run until Ctrl-C would otherwise grow without bound).
    TrackingSummary t;
    t.open_loop_input = run_.openLoopInput();
    std::vector<nodes::CycleRecord> kept;
    MeasurementRecord measurement(c.channels[0].layout.feedback, c.delay_cycles);
    BusLoad load(bitrate_);
    hooks.tap = [&](const canopen::Frame& f, canopen::TimeUs t) { load.add(f, t); };
    hooks.on_record = [&](const nodes::CycleRecord& x) {
      t.add(x);
      if (!run_.csv.empty() || !figure_.empty()) kept.push_back(x);
      if (!run_.out.empty()) measurement.add(x);
    };
    std::fprintf(stderr, "in-process bus: controller (node %u) + sensor (%u) + valve (%u), %g s pre-roll + %s\n",
                 c.node_id ? c.node_id : 1u, c.channels[0].sensor_id, c.channels[0].valve_id, run_.preroll,
                 forever ? "until Ctrl-C" : (std::to_string(run_.duration) + " s run").c_str());
    const auto r = rig::runVirtualRig(c, ec, run_.duration, candump, 1700000000000000, 0, hooks);
    if (!run_.csv.empty()) {
      std::vector<double> tt, yd, y, u, un, uc, yh, f, ch;
      for (const auto& x : kept) {
        tt.push_back(x.t), yd.push_back(x.yd), y.push_back(x.y), u.push_back(x.u), un.push_back(x.u_n),
            uc.push_back(x.u_c), yh.push_back(x.y_hat), f.push_back(x.fault), ch.push_back(x.channel + 1.0);
      }
      std::vector<std::string> names = {"t", "yd", "y", "u", "u_n", "u_c", "y_hat", "fault"};
      std::vector<const std::vector<double>*> cols = {&tt, &yd, &y, &u, &un, &uc, &yh, &f};
      if (c.channels.size() > 1) names.push_back("channel"), cols.push_back(&ch);  // 1-based
      io::writeCsvAtomic(run_.csv, names, cols);
    }
    std::printf("%s controller: %llu frames on the bus, %llu faults%s%s\n",
                control::toString(static_cast<control::Kind>(c.kind)), static_cast<unsigned long long>(r.frames),
                static_cast<unsigned long long>(r.faults), r.final_fault == nodes::Fault::None ? "" : ", last: ",
                r.final_fault == nodes::Fault::None ? "" : nodes::toString(r.final_fault));
    printStats(r.stats, t);
    printJoints(joints_, t);
    load.print();
    if (!figure_.empty()) writeRunFigure(figure_, kept, c.channels.size(), joints_);
    if (!candump.empty()) std::printf("candump log: %s\n", candump.c_str());
    if (!r.failure.empty() && !forever)
      throw std::runtime_error("the loop never started: " + r.failure +
                               "; devices that differ from pamc's own need "
                               "a rig file that describes them (--rig, docs/RIG.md)");
    writeMeasurement(measurement, run_.out);
    return 0;
  }

  OdOption od_;
  RigOption rig_;
  ControllerKindOption kind_;
  ControllerOptions ctrl_;
  NodeRunOptions run_;
  EmulatorOptions emu_;
  RealtimeOptions rt_;
  nodes::EmulatorConfig ec;
  unsigned bitrate_ = 1000000;  // the rig's
  std::vector<nodes::RigJoint> joints_;
  std::string figure_;
  CLI::App *run_cmd_ = nullptr, *faults_cmd_ = nullptr, *soak_cmd_ = nullptr, *guards_cmd_ = nullptr;
  const CLI::App* from_ = nullptr;  // the subcommand parsed (rig itself for the old forms)
  std::string candump, progress;
  // The fault tools' options: rig faults (--only, --rig, --channel), rig soak (--hours, --only, --seed,
  // --report-every), and the old forms' --faults and --sdo-guards.
  struct FaultToolArgs {
    std::string only, rig;
    int channel = 1;  // 1-based
    bool faults = false, sdo_guards = false;
    double soak_hours = 0, report_every = 3600;
    std::uint64_t seed = 1;
  } ft_;
};

}  // namespace

std::unique_ptr<Command> makeRigCommand(CLI::App& app) { return std::make_unique<RigCommand>(app); }

}  // namespace pamc::app
