#include "app/bus_common.hpp"

#include <unistd.h>

#include <sched.h>
#include <signal.h>
#include <sys/mman.h>

#include <cerrno>
#include <cstring>
#include <set>

#include "nodes/rig_file.hpp"
#include "plant/plant.hpp"

namespace pamc::app {

std::atomic<canopen::EventLoop*> g_loop{nullptr};
std::atomic<bool> g_stop{false};

namespace {
void onSignal(int) {
  g_stop = true;
  if (auto* l = g_loop.load()) l->stop();
}
}  // namespace

void installSignals() {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

void realtimeSetup(bool enable, int cpu, int priority) {
  if (!enable) return;
  if (cpu >= 0) {
    cpu_set_t set;
    CPU_ZERO(&set);
    CPU_SET(cpu, &set);
    if (::sched_setaffinity(0, sizeof set, &set) != 0)
      std::fprintf(stderr, "warning: cannot pin to CPU %d (%s)\n", cpu, std::strerror(errno));
  }
  if (priority <= 0) return;  // paced only: normal scheduling, pages not locked
  if (::mlockall(MCL_CURRENT | MCL_FUTURE) != 0)
    std::fprintf(stderr, "warning: mlockall failed (%s): pages may fault in the cycle\n", std::strerror(errno));
  sched_param sp{};
  sp.sched_priority = priority;
  if (::sched_setscheduler(0, SCHED_FIFO, &sp) != 0)
    std::fprintf(stderr, "warning: SCHED_FIFO %d not permitted (%s): running with normal priority\n", priority,
                 std::strerror(errno));
}

void printStats(const nodes::CycleStats& s, const TrackingSummary& t) {
  std::printf("cycles %llu, overruns %llu, missed SYNCs %llu\n", static_cast<unsigned long long>(s.cycles),
              static_cast<unsigned long long>(s.overruns), static_cast<unsigned long long>(s.missed_syncs));
  std::printf("SYNC-to-setpoint latency: median %.1f us, p99 %.1f us, max %.1f us\n", s.latency_us.quantile(0.5),
              s.latency_us.quantile(0.99), s.latency_us.max());
  std::printf("SYNC period jitter: median %.1f us, p99 %.1f us, max %.1f us\n", s.jitter_us.quantile(0.5),
              s.jitter_us.quantile(0.99), s.jitter_us.max());
  double acc = 0, max = 0;
  std::uint64_t n = 0;
  for (std::size_t c = 0; c < t.channels; ++c) acc += t.ch[c].acc, max = std::max(max, t.ch[c].max), n += t.ch[c].n;
  if (n)
    std::printf("tracking error over %llu cycles: RMSE %.4f mm, max %.4f mm\n", static_cast<unsigned long long>(n),
                std::sqrt(acc / static_cast<double>(n)), max);
  for (std::size_t c = 0; c < t.channels; ++c) {
    const auto& x = t.ch[c];
    if (x.n)
      std::printf("channel %zu: tracking RMSE %.4f mm, max %.4f mm over %llu cycles\n", c + 1,
                  std::sqrt(x.acc / static_cast<double>(x.n)), x.max, static_cast<unsigned long long>(x.n));
    else
      std::printf("channel %zu: no cycle tracked%s\n", c + 1, t.open_loop_input ? " (--input: open loop)" : "");
  }
}

nodes::RigFile readRig(const std::string& path) {
  nodes::RigFile rig = nodes::readRigFile(path);
  static std::set<std::string> told;
  if (rig.one_muscle_form && told.insert(path).second)
    std::fprintf(stderr,
                 "notice: %s is in the one-muscle form ([sensor], [valve]): read as channel 1; the form of slaves "
                 "and channels ([slave.NAME], [channel.N]) replaces it (docs/RIG.md, od/rigs/default.ini)\n",
                 path.c_str());
  return rig;
}

void printJoints(const std::vector<nodes::RigJoint>& joints, const TrackingSummary& t) {
  for (std::size_t j = 0; j < joints.size(); ++j) {
    const auto& x = t.ch[joints[j].flexor];
    if (x.n == 0) continue;
    const double deg_per_mm = 180.0 / M_PI / joints[j].lever_mm;
    std::printf("joint %zu (channels %zu, %zu): angle tracking RMSE %.3f deg, max %.3f deg\n", j + 1,
                joints[j].flexor + 1, joints[j].extensor + 1, std::sqrt(x.acc / static_cast<double>(x.n)) * deg_per_mm,
                x.max * deg_per_mm);
  }
}

void BusLoad::print() const {
  const double s = first < 0 ? 0.0 : static_cast<double>(last - first) * 1e-6;
  std::printf("bus load: %.1f %% of %u kbit/s (%llu frames, %llu bits with stuffing, over %.3f s)\n",
              100.0 * meter.load(s, bitrate), bitrate / 1000, static_cast<unsigned long long>(meter.frames()),
              static_cast<unsigned long long>(meter.bits()), s);
}

std::unique_ptr<canopen::SocketCanTransport> openCan(const std::string& iface) {
  try {
    return std::make_unique<canopen::SocketCanTransport>(iface);
  } catch (const std::exception& e) {
    const std::string hint = std::string(e.what()).find("Address family") != std::string::npos
                                 ? " (this kernel has no CAN support: run inside ./vcan_setup.sh vm -- ...)"
                                 : " (bring it up first, e.g. sudo ./vcan_setup.sh up " + iface + ")";
    throw std::runtime_error(std::string(e.what()) + hint);
  }
}

std::string defaultOdDir() {
  auto has = [](const std::string& d) { return ::access((d + "/controller.eds").c_str(), R_OK) == 0; };
  if (has("od")) return "od";
  char exe[4096];
  const ssize_t n = ::readlink("/proc/self/exe", exe, sizeof exe - 1);
  if (n > 0) {
    exe[n] = '\0';
    std::string dir(exe);
    dir.erase(dir.find_last_of('/'));  // .../bin
    for (const char* rel : {"/../share/pamc/od", "/../../od"})
      if (has(dir + rel)) return dir + rel;
  }
  return "od";
}

void OdOption::add(CLI::App* a) {
  a->add_option("--od", dir, "folder with the EDS files (controller.eds, sensor.eds, valve.eds)")
      ->capture_default_str();
}

void BusDictionaryOptions::add(CLI::App* a) {
  a->add_option("--rig", rig,
                "rig file (docs/RIG.md): decode the rig's devices - their COB-IDs and scaling - "
                "as the controller configured them, instead of the EDS files of --od");
  a->add_option("--eds", eds, "further EDS files (devices not in --od or the rig), repeatable");
}

nodes::BusDictionary BusDictionaryOptions::load(const OdOption& od) const {
  if (rig.empty()) {
    std::vector<std::string> paths = eds;
    paths.insert(paths.begin(), od.dir);
    return nodes::loadBusDictionary(paths);
  }
  nodes::BusDictionary d = nodes::busDictionaryFromRig(readRig(rig));
  if (eds.empty()) return d;
  const nodes::BusDictionary more = nodes::loadBusDictionary(eds);
  d.pdos.insert(more.pdos.begin(), more.pdos.end());  // the rig's COB-IDs win
  d.nodes.insert(more.nodes.begin(), more.nodes.end());
  return d;
}

void EmulatorOptions::add(CLI::App* a) {
  a->add_option("--plant", plant_file, "plant emulator config (JSON)");
  a->add_option("--sensor-silent-at", ec.sensor_silent_at_s, "the sensor node goes silent at this time [s]");
  a->add_option("--sensor-silent-for", ec.sensor_silent_for_s, "... for this long [s]");
  a->add_option("--drop-pdo", ec.drop_pdo_prob, "probability of dropping each position PDO")
      ->check(CLI::Range(0.0, 1.0));
  a->add_option("--late-pdo", ec.late_pdo_cycles, "position PDOs this many cycles late")->check(CLI::Range(0, 255));
  a->add_option("--payload", payload, "payload step TIME:NEWTONS, e.g. 10:40");
  a->add_flag(
      "--profile-defaults", profile_defaults,
      "play off-the-shelf devices with their makers' defaults instead of pamc's own (od/profile/: a CiA 406 "
      "encoder, node 16, 5 um steps, asynchronous PDO; a CiA 401 analog I/O module, node 32, valve on output 2, "
      "no heartbeats): only a controller that configures them (--rig od/rigs/profile.ini) can use them");
}

nodes::EmulatorConfig EmulatorOptions::config(const std::string& od_dir, unsigned period_us) const {
  nodes::EmulatorConfig e = ec;
  if (profile_defaults) {
    e.useProfileDevices(od_dir);
  } else {
    e.sensor_eds = od_dir + "/sensor.eds";
    e.valve_eds = od_dir + "/valve.eds";
  }
  if (!plant_file.empty()) e.plant = plant::PlantConfig::fromFile(plant_file);
  if (period_us) e.plant.Ts = period_us * 1e-6;  // the emulator steps one SYNC period per SYNC
  if (!payload.empty()) {
    const auto c = payload.find(':');
    if (c == std::string::npos) throw std::invalid_argument("--payload: expected TIME:NEWTONS, got '" + payload + "'");
    try {
      e.payload.at_s = std::stod(payload.substr(0, c));
      e.payload.N = std::stod(payload.substr(c + 1));
    } catch (const std::exception&) {
      throw std::invalid_argument("--payload: expected TIME:NEWTONS with numbers, got '" + payload + "'");
    }
  }
  return e;
}

void RealtimeOptions::add(CLI::App* a, const std::string& what, const std::string& new_path) {
  a->add_flag("--realtime", rt,
              what + "; SCHED_FIFO at --priority, mlockall, pinned to --cpu (a warning when not permitted)");
  addOldFlag(a, "--rt", (new_path.empty() ? commandPath(a) : new_path) + " --realtime", rt);
  a->add_option("--cpu", cpu, "with --realtime: pin the process to this CPU");
  a->add_option("--priority", priority,
                "with --realtime: SCHED_FIFO priority and mlockall (0: normal scheduling, no mlockall)")
      ->capture_default_str()
      ->check(CLI::Range(0, 99));
}

void InterfaceOption::add(CLI::App* a, bool with_rig) {
  a->add_option("--iface", name,
                std::string("CAN interface (can0, vcan0, ...; default: ") + (with_rig ? "the rig file's, else " : "") +
                    nodes::kDefaultInterface + ")");
}

std::string InterfaceOption::resolve(const std::string& rig_file) const {
  if (!name.empty()) return name;
  return rig_file.empty() ? std::string(nodes::kDefaultInterface) : readRig(rig_file).interface;
}

}  // namespace pamc::app
