#include "app/bus_commands.hpp"

#include <fcntl.h>
#include <sched.h>
#include <signal.h>
#include <sys/mman.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <thread>

#include "canopen/candump_log.hpp"
#include "canopen/event_loop.hpp"
#include "canopen/socketcan.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/decoder.hpp"
#include "nodes/emulator_node.hpp"
#include "rig/fault_rig.hpp"
#include "nodes/monitor.hpp"
#include "rig/virtual_rig.hpp"
#include "sim/trajectory.hpp"

namespace pamc::app {

namespace {

std::atomic<canopen::EventLoop*> g_loop{nullptr};
std::atomic<bool> g_stop{false};
void onSignal(int) {
  g_stop = true;
  if (auto* l = g_loop.load()) l->stop();
}

void installSignals() {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

// Real-time set-up when permitted, a warning when not.
void realtimeSetup(bool enable, int cpu, int priority) {
  if (!enable) return;
  if (::mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    std::fprintf(stderr, "warning: mlockall failed (%s): pages may fault in the cycle\n", std::strerror(errno));
  sched_param sp{};
  sp.sched_priority = priority;
  if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
    std::fprintf(stderr, "warning: SCHED_FIFO %d not permitted (%s): running with normal priority\n", priority,
                 std::strerror(errno));
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    if (::sched_setaffinity(0, sizeof set, &set) != 0)
      std::fprintf(stderr, "warning: cannot pin to CPU %d (%s)\n", cpu, std::strerror(errno));
  }
}

// Joins a watcher thread however the event loop ends (a destroyed joinable thread would abort).
struct Joiner {
  std::thread& t;
  ~Joiner() {
    g_stop = true;
    if (t.joinable()) t.join();
  }
};

// Tracking error of the cycles in control (no fault), for the summary at the end.
struct TrackingSummary {
  double acc = 0, max = 0;
  std::uint64_t n = 0;
  void add(const nodes::CycleRecord& r) {
    if (r.fault != 0) return;
    const double e = r.yd - r.y;
    acc += e * e;
    max = std::max(max, std::fabs(e));
    ++n;
  }
};

struct LogItem {
  canopen::Frame frame;
  canopen::TimeUs unix_us;
};

// Formats frames and cycle records off the real-time thread and hands them to the kernel once per
// SYNC period (one write(2) per file when there is something new), so a crash or kill -9 loses at most
// the records of the last cycle or two: those still in the ring. Data handed over survives the death
// of the process in the page cache, so no fsync (the kernel writes it back within seconds; only a
// power failure or a kernel crash in that time would lose it).
class Logger {
 public:
  // period_us: how often the files are brought up to date (the SYNC period).
  Logger(const std::string& candump, const std::string& iface, const std::string& csv, unsigned period_us)
      : period_(std::chrono::microseconds(period_us ? period_us : 1000)) {
    if (!candump.empty()) dump_ = std::make_unique<canopen::CandumpWriter>(candump, iface);
    if (!csv.empty()) {
      csv_ = std::fopen(csv.c_str(), "w");
      if (!csv_) throw std::runtime_error(csv + ": cannot write");
      std::fprintf(csv_, "t,yd,y,u,u_n,u_c,y_hat,fault,latency_us\n");
      std::fflush(csv_);
    }
  }
  ~Logger() {
    stop();
    if (csv_) std::fclose(csv_);
  }
  nodes::SpscRing<LogItem, 1 << 16> frames;
  nodes::SpscRing<nodes::CycleRecord, 1 << 15>* records = nullptr;
  void start() {
    thread_ = std::thread([this] {
      while (!quit_) {
        drain();
        std::this_thread::sleep_for(period_);
      }
      drain();
    });
  }
  void stop() {
    quit_ = true;
    if (thread_.joinable()) thread_.join();
  }
  TrackingSummary summary;  // accumulated, so a node running for days does not grow

 private:
  void drain() {
    LogItem it;
    bool wrote = false;
    while (frames.pop(it)) {
      if (!dump_) continue;
      dump_->write(it.frame, it.unix_us);
      wrote = true;
    }
    if (dump_ && wrote) dump_->flush();
    nodes::CycleRecord r;
    wrote = false;
    while (records && records->pop(r)) {
      summary.add(r);
      if (csv_) {
        std::fprintf(csv_, "%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%u,%.1f\n", r.t, r.yd, r.y, r.u, r.u_n, r.u_c, r.y_hat,
                     r.fault, static_cast<double>(r.latency_us));
        wrote = true;
      }
    }
    if (csv_ && wrote) std::fflush(csv_);
  }
  std::unique_ptr<canopen::CandumpWriter> dump_;
  std::FILE* csv_ = nullptr;
  std::chrono::microseconds period_;
  std::thread thread_;
  std::atomic<bool> quit_{false};
};

void printStats(const nodes::CycleStats& s, const TrackingSummary& t) {
  std::printf("cycles %llu, overruns %llu, missed SYNCs %llu\n", static_cast<unsigned long long>(s.cycles),
              static_cast<unsigned long long>(s.overruns), static_cast<unsigned long long>(s.missed_syncs));
  std::printf("SYNC-to-setpoint latency: median %.1f us, p99 %.1f us, max %.1f us\n", s.latency_us.quantile(0.5),
              s.latency_us.quantile(0.99), s.latency_us.max());
  std::printf("SYNC period jitter: median %.1f us, p99 %.1f us, max %.1f us\n", s.jitter_us.quantile(0.5),
              s.jitter_us.quantile(0.99), s.jitter_us.max());
  if (t.n)
    std::printf("tracking error over %llu cycles: RMSE %.4f mm, max %.4f mm\n", static_cast<unsigned long long>(t.n),
                std::sqrt(t.acc / static_cast<double>(t.n)), t.max);
}

}  // namespace

struct BusCommands::Impl {
  CLI::App *rig = nullptr, *controller = nullptr, *emulator = nullptr, *decode = nullptr, *monitor = nullptr;
  // controller options
  std::string iface = "vcan0", od_dir = "od", ctrl_kind = "pi", traj = "triangle:0.05:0.2:30", model_file, plant_file;
  double duration = 40.0, preroll = 5.0;
  double emu_duration = 0.0;  // the emulator runs until stopped unless told
  unsigned period_us = 0;
  bool consume_sync = false, rt = false;
  int cpu = -1, prio = 80;
  std::string candump, csv;
  control::ControllerConfig cc;
  // emulator options
  nodes::EmulatorConfig ec;
  std::string payload;
  // decode / monitor
  std::string log_in, out;
  std::vector<std::string> od_paths;
  bool once = false;
  // rig --faults / --sdo-guards / --soak / --realtime
  bool faults = false, sdo_guards = false;
  std::string only;
  double soak_hours = 0, report_every = 3600;
  std::uint64_t seed = 1;
  bool realtime = false;
  std::string progress;

  void addControllerOptions(CLI::App* a) {
    a->add_option("--od", od_dir, "directory with controller.eds, sensor.eds, valve.eds")->capture_default_str();
    a->add_option("--controller", ctrl_kind, "open, pi, eso or amc")->capture_default_str();
    a->add_option("--trajectory", traj, "desired position: triangle:F:LO:HI, sinedesc:F:C:A0:A1:T, square:F:LO:HI, ...")
        ->capture_default_str();
    a->add_option("--duration", duration, "seconds of trajectory (0: until stopped)")->capture_default_str();
    a->add_option("--preroll", preroll, "seconds holding the first setpoint before the trajectory")->capture_default_str();
    a->add_option("--model", model_file, "identified model (JSON) for the AMC's UKF and the open loop");
    a->add_option("--kp", cc.kp, "[V/mm]")->capture_default_str();
    a->add_option("--ki", cc.ki, "[V/(mm s)]")->capture_default_str();
    a->add_option("--kc", cc.kc, "[V/mm]")->capture_default_str();
    a->add_option("--csv", csv, "write the cycle records (t,yd,y,u,...) here");
    a->add_option("--period-us", period_us, "SYNC period (default: 0x1006 of the EDS, 1000 us)")->check(CLI::Range(100u, 1000000u));
  }
  void addEmulatorOptions(CLI::App* a) {
    a->add_option("--plant", plant_file, "plant emulator config (JSON)");
    a->add_option("--sensor-silent-at", ec.sensor_silent_at_s, "the sensor node goes silent at this time [s]");
    a->add_option("--sensor-silent-for", ec.sensor_silent_for_s, "... for this long [s]");
    a->add_option("--drop-pdo", ec.drop_pdo_prob, "probability of dropping each position PDO")->check(CLI::Range(0.0, 1.0));
    a->add_option("--late-pdo", ec.late_pdo_cycles, "position PDOs this many cycles late")->check(CLI::Range(0, 255));
    a->add_option("--payload", payload, "payload step TIME:NEWTONS, e.g. 10:40");
  }
  // Opens the interface with a hint on what to do when it is not there.
  std::unique_ptr<canopen::SocketCanTransport> openCan() {
    try {
      return std::make_unique<canopen::SocketCanTransport>(iface);
    } catch (const std::exception& e) {
      const std::string hint = std::string(e.what()).find("Address family") != std::string::npos
                                   ? " (this kernel has no CAN support: run inside ./vcan_setup.sh vm -- ...)"
                                   : " (bring it up first, e.g. sudo ./vcan_setup.sh up " + iface + ")";
      throw std::runtime_error(std::string(e.what()) + hint);
    }
  }
  void prepare() {
    if (!model_file.empty()) cc.model = io::readModelFile(model_file);
    if (!plant_file.empty()) ec.plant = plant::PlantConfig::fromFile(plant_file);
    if (period_us) ec.plant.Ts = period_us * 1e-6;  // the emulator steps one SYNC period per SYNC
    ec.sensor_eds = od_dir + "/sensor.eds";
    ec.valve_eds = od_dir + "/valve.eds";
    if (!payload.empty()) {
      const auto c = payload.find(':');
      if (c == std::string::npos) throw std::invalid_argument("--payload: expected TIME:NEWTONS, got '" + payload + "'");
      try {
        ec.payload_at_s = std::stod(payload.substr(0, c));
        ec.payload_N = std::stod(payload.substr(c + 1));
      } catch (const std::exception&) {
        throw std::invalid_argument("--payload: expected TIME:NEWTONS with numbers, got '" + payload + "'");
      }
    }
  }
  nodes::ControllerNodeConfig controllerConfig() {
    nodes::ControllerNodeConfig c;
    c.eds_path = od_dir + "/controller.eds";
    c.kind = static_cast<int>(control::kindFromString(ctrl_kind));
    c.ctrl = cc;
    c.gains_from_config = true;
    c.has_trajectory = true;
    c.trajectory = sim::Trajectory::parse(traj);
    c.preroll_s = preroll;
    c.produce_sync = !consume_sync;
    c.period_us = period_us;
    if ((c.kind == static_cast<int>(control::Kind::PiAmc) || c.kind == static_cast<int>(control::Kind::OpenLoop)) &&
        model_file.empty())
      std::fprintf(stderr, "warning: no --model: the %s controller uses the model parameters of the EDS defaults\n",
                   ctrl_kind.c_str());
    return c;
  }

  // --only: names of the fault catalogue (an unknown name lists them).
  std::vector<nodes::BusFault> faultList() const {
    std::vector<nodes::BusFault> list;
    std::string rest = only;
    while (!rest.empty()) {
      const auto c = rest.find(',');
      const std::string name = rest.substr(0, c);
      rest = c == std::string::npos ? "" : rest.substr(c + 1);
      bool found = false;
      for (auto f : nodes::allBusFaults())
        if (name == nodes::busFaultName(f)) list.push_back(f), found = true;
      if (!found) {
        std::string names;
        for (auto f : nodes::allBusFaults()) names += std::string(names.empty() ? "" : ", ") + nodes::busFaultName(f);
        throw std::invalid_argument("--only: unknown fault '" + name + "' (one of: " + names + ")");
      }
    }
    return list;
  }

  // The fault table and the parameter guard, reproduced on the in-process rig (docs/RELIABILITY.md).
  int runRigChecks() {
    nodes::FaultRigOptions o;
    o.od_dir = od_dir;
    if (sdo_guards) {
      std::printf("%s", nodes::guardTableMarkdown(nodes::runParameterGuards(o)).c_str());
      if (!faults) return 0;
      std::printf("\n");
    }
    const auto list = faultList();
    std::fprintf(stderr, "in-process bus, %s, fault injected after %g s of a 0.2 Hz sine, run on %g s after it cleared\n",
                 control::toString(o.kind), o.inject_at_s, o.after_s);
    std::printf("%s", nodes::faultTableMarkdown(nodes::runFaultTable(list, o)).c_str());
    return 0;
  }

  // Hours of virtual time with random faults: memory, cycle, tracking after every fault (docs/RELIABILITY.md).
  int runSoak() {
    nodes::SoakOptions o;
    o.od_dir = od_dir;
    o.hours = soak_hours;
    o.seed = seed;
    o.report_s = report_every;
    o.faults = faultList();
    // The fault table's controller and gains unless given.
    if (rig->count("--controller")) o.kind = control::kindFromString(ctrl_kind);
    if (rig->count("--kp")) o.kp = cc.kp;
    if (rig->count("--ki")) o.ki = cc.ki;
    if (rig->count("--kc")) o.kc = cc.kc;
    std::fprintf(stderr,
                 "soak: %g h of 1 kHz cycles in virtual time, %s (kp %g, ki %g, kc %g), 0.2 Hz sine 10-20 mm; "
                 "controller consuming the SYNC of a producer node, 1 Mbit/s bus; faults (%zu kinds) every %g-%g s "
                 "after the last check, seed %llu\n",
                 o.hours, control::toString(o.kind), o.kp, o.ki, o.kc,
                 o.faults.empty() ? nodes::allBusFaults().size() : o.faults.size(), o.gap_min_s, o.gap_max_s,
                 static_cast<unsigned long long>(o.seed));
    std::printf("%s", nodes::soakIntervalHeader().c_str());
    std::fflush(stdout);
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = nodes::runSoak(
        o,
        [](const nodes::SoakInterval& i) {
          std::printf("%s", nodes::soakIntervalLine(i).c_str());
          std::fflush(stdout);
        },
        [&](double sim_s) {
          if (std::fmod(sim_s, 600.0) > 1.0) return;  // every 10 simulated minutes
          const double wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
          const double total = o.hours * 3600.0;
          std::fprintf(stderr, "soak: %.2f of %g h simulated, %.0f s wall, about %.0f s to go\n", sim_s / 3600.0,
                       o.hours, wall, wall / sim_s * (total - sim_s));
        });
    std::printf("%s", nodes::soakReport(o, r, false).c_str());  // the intervals are printed above
    return r.passed() ? 0 : 1;
  }

  // The rig paced in real time, logging like the nodes on SocketCAN: frames and records go through the
  // logger thread's rings and reach the files within a millisecond.
  int runRigRealtime(const nodes::ControllerNodeConfig& c) {
    auto ring = std::make_unique<nodes::SpscRing<nodes::CycleRecord, 1 << 15>>();
    auto loggerp = std::make_unique<Logger>(candump, "vcan0", csv, period_us);
    auto& logger = *loggerp;
    logger.records = ring.get();
    int progress_fd = -1;
    if (!progress.empty()) {
      progress_fd = ::open(progress.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_APPEND | O_CLOEXEC, 0644);
      if (progress_fd < 0) throw std::runtime_error(progress + ": cannot write");
    }
    timespec wall{};
    ::clock_gettime(CLOCK_REALTIME, &wall);
    const canopen::TimeUs epoch = static_cast<canopen::TimeUs>(wall.tv_sec) * 1000000 + wall.tv_nsec / 1000;
    nodes::VirtualRigHooks hooks;
    hooks.realtime = true;
    hooks.tap = [&](const canopen::Frame& f, canopen::TimeUs t) { logger.frames.push({f, epoch + t}); };
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
        const int n = std::snprintf(b, sizeof b, "cycle %u t %.3f bus_us %lld\n", last.k, last.t, static_cast<long long>(now));
        if (::write(progress_fd, b, static_cast<size_t>(n)) < 0) progress_fd = -1;
        fresh = false;
      }
      return !g_stop.load();
    };
    installSignals();
    logger.start();
    std::fprintf(stderr, "in-process bus paced in real time: controller (node 1) + sensor (2) + valve (3), %g s pre-roll + %s\n",
                 preroll, duration > 0 ? (std::to_string(duration) + " s run").c_str() : "run until stopped");
    const auto r = nodes::runVirtualRig(c, ec, duration, "", epoch, 0, hooks);
    logger.stop();
    if (progress_fd >= 0) ::close(progress_fd);
    std::printf("%llu frames on the bus, %llu faults%s%s\n", static_cast<unsigned long long>(r.frames),
                static_cast<unsigned long long>(r.faults), r.final_fault == nodes::Fault::None ? "" : ", last: ",
                r.final_fault == nodes::Fault::None ? "" : nodes::toString(r.final_fault));
    printStats(r.stats, logger.summary);
    return 0;
  }

  int runRig() {
    if (soak_hours > 0) return runSoak();
    if (faults || sdo_guards) return runRigChecks();
    prepare();
    const auto c = controllerConfig();
    if (realtime) return runRigRealtime(c);
    std::fprintf(stderr, "in-process bus: controller (node 1) + sensor (2) + valve (3), %g s pre-roll + %g s run\n",
                 preroll, duration);
    const auto r = nodes::runVirtualRig(c, ec, duration, candump);
    if (!csv.empty()) {
      std::vector<double> t, yd, y, u, un, uc, yh, f;
      for (const auto& x : r.records) {
        t.push_back(x.t), yd.push_back(x.yd), y.push_back(x.y), u.push_back(x.u), un.push_back(x.u_n),
            uc.push_back(x.u_c), yh.push_back(x.y_hat), f.push_back(x.fault);
      }
      io::writeCsvAtomic(csv, {"t", "yd", "y", "u", "u_n", "u_c", "y_hat", "fault"}, {&t, &yd, &y, &u, &un, &uc, &yh, &f});
    }
    std::printf("%llu frames on the bus, %llu faults%s%s\n", static_cast<unsigned long long>(r.frames),
                static_cast<unsigned long long>(r.faults), r.final_fault == nodes::Fault::None ? "" : ", last: ",
                r.final_fault == nodes::Fault::None ? "" : nodes::toString(r.final_fault));
    TrackingSummary t;
    for (const auto& x : r.records) t.add(x);
    printStats(r.stats, t);
    if (!candump.empty()) std::printf("candump log: %s\n", candump.c_str());
    return 0;
  }

  int runController() {
    prepare();
    auto c = controllerConfig();
    realtimeSetup(rt, cpu, prio);
    auto canp = openCan();
    auto& can = *canp;
    // On the heap: the record rings are megabytes.
    auto nodep = std::make_unique<nodes::ControllerNode>(c, can, [] { return canopen::monotonicNowUs(); });
    auto& node = *nodep;
    auto loggerp = std::make_unique<Logger>(candump, iface, csv, c.period_us);
    auto& logger = *loggerp;
    logger.records = &node.records();
    can.setTap([&](const canopen::Frame& f, canopen::TimeUs t, bool) { logger.frames.push({f, t}); });
    canopen::EventLoop loop(can, node.node());
    g_loop = &loop;
    installSignals();
    logger.start();
    std::fprintf(stderr, "controller node 1 on %s: %s, %s%s\n", iface.c_str(), control::toString(node.kind()),
                 c.trajectory.describe().c_str(), c.produce_sync ? ", producing SYNC" : ", consuming SYNC");
    std::thread watch([&] {
      nodes::Fault last = nodes::Fault::None;
      while (!g_stop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        const auto f = node.fault();
        if (f != last) {
          if (f == nodes::Fault::IdCollision)
            std::fprintf(stderr, "fault: %s (frame on COB-ID 0x%03X from another node) -> valve to its safe value, "
                         "EMCY 0x%04X sent\n", nodes::toString(f), node.lastCollisionCob(), nodes::emcyCode(f));
          else if (f != nodes::Fault::None)
            std::fprintf(stderr, "fault: %s -> valve to its safe value, EMCY 0x%04X sent\n", nodes::toString(f),
                         nodes::emcyCode(f));
          else
            std::fprintf(stderr, "fault cleared: estimator and integrator restarted\n");
          last = f;
        }
        if (duration > 0 && node.runTime() >= duration) loop.stop();
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
    const auto& st = can.stats();
    std::printf("socket: rx %llu, tx %llu, tx queued %llu, tx dropped %llu, tx expired %llu, error frames %llu\n",
                static_cast<unsigned long long>(st.rx_frames), static_cast<unsigned long long>(st.tx_frames),
                static_cast<unsigned long long>(st.tx_queued), static_cast<unsigned long long>(st.tx_dropped),
                static_cast<unsigned long long>(st.tx_expired), static_cast<unsigned long long>(st.error_frames));
    return 0;
  }

  int runEmulator() {
    prepare();
    realtimeSetup(rt, cpu, prio);
    auto canp = openCan();
    auto& can = *canp;
    auto emup = std::make_unique<nodes::EmulatorNodes>(ec, can);
    auto& emu = *emup;
    auto loggerp = std::make_unique<Logger>(candump, iface, "", period_us);
    auto& logger = *loggerp;
    can.setTap([&](const canopen::Frame& f, canopen::TimeUs t, bool) { logger.frames.push({f, t}); });
    canopen::EventLoop loop(can, emu);
    g_loop = &loop;
    installSignals();
    logger.start();
    std::fprintf(stderr, "emulator on %s: sensor node %u, valve node %u; stepped by SYNC\n", iface.c_str(),
                 emu.sensor().nodeId(), emu.valve().nodeId());
    std::thread watch([&] {
      while (!g_stop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        if (emu_duration > 0 && emu.time() >= emu_duration) loop.stop();
      }
    });
    {
      Joiner j{watch};
      emu.start(canopen::monotonicNowUs());
      loop.run();
    }
    g_loop = nullptr;
    logger.stop();
    std::printf("emulated %.3f s (%llu position PDOs dropped by fault injection)\n", emu.time(),
                static_cast<unsigned long long>(emu.pdosDropped()));
    return 0;
  }

  int runDecode() {
    const auto dict = nodes::loadBusDictionary(od_paths.empty() ? std::vector<std::string>{od_dir} : od_paths);
    std::string warning;
    const auto log = canopen::readCandumpLog(log_in, &warning);
    if (!warning.empty()) std::fprintf(stderr, "warning: %s\n", warning.c_str());
    const auto run = nodes::decodeCandump(log, dict);
    if (run.rows.size() < 3)
      throw std::runtime_error(log_in + ": no complete cycles (SYNC, position and valve command) found in the log");
    std::string text;
    for (size_t i = 0; i < run.columns.size(); ++i) text += (i ? "," : "") + run.columns[i];
    text += '\n';
    char b[64];
    for (const auto& r : run.rows) {
      for (size_t i = 0; i < r.size(); ++i) {
        if (std::isnan(r[i])) std::snprintf(b, sizeof b, "%s", i ? "," : "");
        else std::snprintf(b, sizeof b, "%s%.9g", i ? "," : "", r[i]);
        text += b;
      }
      text += '\n';
    }
    const std::string dst = out.empty() ? log_in + ".csv" : out;
    io::writeFileAtomic(dst, text);
    if (run.held)
      std::fprintf(stderr, "warning: %llu cycles had no position PDO; their position holds the last value\n",
                   static_cast<unsigned long long>(run.held));
    std::printf("%s: %llu frames, %llu SYNCs -> %zu rows (%zu columns) in %s; %llu frames of unknown COB-ID, %llu of "
                "wrong length\n",
                log_in.c_str(), static_cast<unsigned long long>(run.frames), static_cast<unsigned long long>(run.syncs),
                run.rows.size(), run.columns.size(), dst.c_str(), static_cast<unsigned long long>(run.unknown),
                static_cast<unsigned long long>(run.bad_length));
    return 0;
  }

  int runMonitor() {
    auto dict = nodes::loadBusDictionary(od_paths.empty() ? std::vector<std::string>{od_dir} : od_paths);
    nodes::Monitor mon(dict);
    if (!log_in.empty()) {
      std::string warning;
      const auto log = canopen::readCandumpLog(log_in, &warning);
      if (!warning.empty()) std::fprintf(stderr, "warning: %s\n", warning.c_str());
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
    auto canp = openCan();  // listen only: the monitor never sends
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
};

BusCommands::BusCommands(CLI::App& app) : impl_(std::make_unique<Impl>()) {
  auto& m = *impl_;
  m.rig = app.add_subcommand("rig", "controller and emulator as CANopen nodes on the in-process bus (virtual time, "
                                    "no CAN hardware): the whole rig through the CANopen layer; also the fault table "
                                    "(--faults), the SDO guards (--sdo-guards) and the soak (--soak HOURS)");
  m.addControllerOptions(m.rig);
  m.addEmulatorOptions(m.rig);
  m.rig->add_option("--log", m.candump, "write every frame as a candump -l log");
  m.rig->add_flag("--faults", m.faults,
                  "run each fault on the bus (seeded) and print the fault table: reaction, cycles to the safe "
                  "valve value, EMCY, recovery, data lost");
  m.rig->add_option("--only", m.only, "with --faults or --soak: comma list of faults, e.g. sync-stop,bus-off (an unknown name lists them)");
  m.rig->add_flag("--sdo-guards", m.sdo_guards, "write parameters over SDO to the running controller and print "
                                                "the abort codes and what the loop saw");
  m.rig->add_option("--soak", m.soak_hours,
                    "soak: HOURS of 1 kHz cycles in virtual time (PI + AMC kp 0.1, ki 1.5, kc 0.06 unless --controller, "
                    "--kp, --ki, --kc are given; a 0.2 Hz sine; the controller consuming "
                    "the SYNC of a producer node, 1 Mbit/s bus) with faults of the catalogue injected one after the "
                    "other at random times; prints per report interval the cycles, SYNC gaps, faults, tracking "
                    "after each fault against the no-fault baseline, heap and RSS, CPU per cycle; exit 1 if memory "
                    "grew, a cycle was lost outside a fault, tracking did not come back or left its level between faults, or "
                    "CPU per cycle drifted")
      ->check(CLI::PositiveNumber);
  m.rig->add_option("--seed", m.seed, "with --soak: seed of the fault times, fault choices and sensor noise")->capture_default_str();
  m.rig->add_option("--report-every", m.report_every, "with --soak: simulated seconds per report line")
      ->capture_default_str()
      ->check(CLI::Range(1.0, 1e6));
  auto* rt_flag = m.rig->add_flag("--realtime", m.realtime,
                                  "pace the rig to the wall clock (1 ms of bus time per ms) like a live node: --log "
                                  "and --csv (t,yd,y,u,u_n,u_c,y_hat,fault,latency_us) are streamed by a logger thread "
                                  "and on disk within a millisecond, the log's times are wall-clock times; "
                                  "--duration 0 runs until Ctrl-C");
  m.rig->add_option("--progress", m.progress, "with --realtime: append 'cycle K t T bus_us B' to this file as each "
                                              "cycle is computed (a marker for crash tests and watchdogs)")
      ->needs(rt_flag);

  m.controller = app.add_subcommand("controller", "run the controller node on a SocketCAN interface");
  m.controller->add_option("--iface", m.iface, "CAN interface (can0, vcan0, ...)")->capture_default_str();
  m.addControllerOptions(m.controller);
  m.controller->add_flag("--consume-sync", m.consume_sync, "another master produces SYNC");
  m.controller->add_option("--log", m.candump, "write every frame as a candump -l log");
  m.controller->add_flag("--rt", m.rt, "mlockall, SCHED_FIFO, CPU affinity (warns when not permitted)");
  m.controller->add_option("--cpu", m.cpu, "pin to this CPU with --rt");
  m.controller->add_option("--priority", m.prio, "SCHED_FIFO priority with --rt")->capture_default_str();

  m.emulator = app.add_subcommand("emulator", "play the valve and sensor nodes with the emulator physics on SocketCAN");
  m.emulator->add_option("--iface", m.iface, "CAN interface")->capture_default_str();
  m.emulator->add_option("--od", m.od_dir, "directory with sensor.eds and valve.eds")->capture_default_str();
  m.addEmulatorOptions(m.emulator);
  m.emulator->add_option("--duration", m.emu_duration, "stop after this many seconds of SYNCs (0: until stopped)")->capture_default_str();
  m.emulator->add_option("--period-us", m.period_us, "SYNC period the physics steps by (default 1000 us)");
  m.emulator->add_option("--log", m.candump, "write every frame as a candump -l log");
  m.emulator->add_flag("--rt", m.rt, "mlockall, SCHED_FIFO, CPU affinity (warns when not permitted)");

  m.decode = app.add_subcommand("decode", "turn a candump log into a measurement CSV (t,u,y,p,...) through the PDO "
                                          "mappings of the EDS files");
  m.decode->add_option("log", m.log_in, "candump -l log (from candump or the nodes)")->required();
  m.decode->add_option("--od", m.od_paths, "EDS files or directories (default: od/)");
  m.decode->add_option("--out", m.out, "CSV to write (default: LOG.csv)");

  m.monitor = app.add_subcommand("monitor", "passive live view of a bus decoded through the EDS files");
  m.monitor->add_option("--iface", m.iface, "CAN interface")->capture_default_str();
  m.monitor->add_option("--log", m.log_in, "replay a candump log instead of listening");
  m.monitor->add_option("--od", m.od_paths, "EDS files or directories (default: od/)");
  m.monitor->add_option("--duration", m.duration, "stop after this many seconds (0: until Ctrl-C)");
  m.monitor->add_flag("--once", m.once, "print one screen at the end and exit");
}

BusCommands::~BusCommands() = default;

int BusCommands::run() {
  auto& m = *impl_;
  if (*m.rig) return m.runRig();
  if (*m.controller) return m.runController();
  if (*m.emulator) return m.runEmulator();
  if (*m.decode) return m.runDecode();
  if (*m.monitor) return m.runMonitor();
  return -1;
}

}  // namespace pamc::app
