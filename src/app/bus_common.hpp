// What the bus commands (rig, controller, emulator, decode, monitor) share: signals, the real-time
// set-up, the logger thread that keeps formatting off the cycle, the end-of-run statistics, and the
// option groups of the nodes (one struct per concern).
#pragma once

#include <CLI/CLI.hpp>

#include <algorithm>
#include <array>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>

#include "canopen/candump_log.hpp"
#include "canopen/event_loop.hpp"
#include "canopen/frame_bits.hpp"
#include "canopen/socketcan.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/decoder.hpp"
#include "nodes/emulator_node.hpp"
#include "nodes/rig_file.hpp"
#include "app/command.hpp"
#include "app/measurement_record.hpp"

namespace pamc::app {

extern std::atomic<canopen::EventLoop*> g_loop;
extern std::atomic<bool> g_stop;
void installSignals();
// Real-time set-up when permitted, a warning when not.
void realtimeSetup(bool enable, int cpu, int priority);

// Joins a watcher thread however the event loop ends (a destroyed joinable thread would abort).
struct Joiner {
  std::thread& t;
  ~Joiner() {
    g_stop = true;
    if (t.joinable()) t.join();
  }
};

// Tracking error of the cycles in control (no fault), for the summary at the end.
// Tracking error of each channel over the records (faulted cycles left out).
struct TrackingSummary {
  struct Channel {
    double acc = 0, max = 0;
    std::uint64_t n = 0;
  };
  std::array<Channel, nodes::kMaxChannels> ch{};
  std::size_t channels = 0;      // the highest channel seen + 1
  bool open_loop_input = false;  // --input: the "setpoint" is the command, there is nothing tracked
  void add(const nodes::CycleRecord& r) {
    if (r.channel >= ch.size()) return;
    channels = std::max<std::size_t>(channels, r.channel + 1u);
    if (r.fault != 0 || open_loop_input) return;
    Channel& c = ch[r.channel];
    const double e = r.yd - r.y;
    c.acc += e * e;
    c.max = std::max(c.max, std::fabs(e));
    ++c.n;
  }
};

// The bus load from the frames that went over the bus, each with its stuff bits (canopen::frameBits),
// over the time from the first frame to the last, at the rig's bit rate.
struct BusLoad {
  explicit BusLoad(unsigned bitrate) : bitrate(bitrate) {}
  void add(const canopen::Frame& f, canopen::TimeUs t) {
    meter.add(f);
    if (first < 0) first = t;
    last = t;
  }
  void print() const;  // "bus load: 27.9 % of 1000 kbit/s (...)"
  canopen::BusLoadMeter meter;
  canopen::TimeUs first = -1, last = 0;
  unsigned bitrate;
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
  // period_us: how often the files are brought up to date (the SYNC period). With several channels the
  // CSV has a last column `channel` (1-based).
  Logger(const std::string& candump, const std::string& iface, const std::string& csv, unsigned period_us,
         std::size_t channels = 1)
      : period_(std::chrono::microseconds(period_us ? period_us : 1000)), channel_column_(channels > 1) {
    if (!candump.empty()) dump_ = std::make_unique<canopen::CandumpWriter>(candump, iface);
    if (!csv.empty()) {
      csv_ = std::fopen(csv.c_str(), "w");
      if (!csv_) throw std::runtime_error(csv + ": cannot write");
      std::fprintf(csv_, "t,yd,y,u,u_n,u_c,y_hat,fault,latency_us%s\n", channel_column_ ? ",channel" : "");
      std::fflush(csv_);
    }
  }
  ~Logger() {
    stop();
    if (csv_) std::fclose(csv_);
  }
  nodes::SpscRing<LogItem, 1 << 16> frames;
  nodes::SpscRing<nodes::CycleRecord, 1 << 15>* records = nullptr;
  MeasurementRecord* measurement = nullptr;  // --out: the records as a measurement, written at the end
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
      if (measurement) measurement->add(r);
      if (csv_) {
        std::fprintf(csv_, "%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%u,%.1f", r.t, r.yd, r.y, r.u, r.u_n, r.u_c, r.y_hat,
                     r.fault, static_cast<double>(r.latency_us));
        if (channel_column_) std::fprintf(csv_, ",%u", r.channel + 1u);
        std::fputc('\n', csv_);
        wrote = true;
      }
    }
    if (csv_ && wrote) std::fflush(csv_);
  }
  std::unique_ptr<canopen::CandumpWriter> dump_;
  std::FILE* csv_ = nullptr;
  std::chrono::microseconds period_;
  bool channel_column_;
  std::thread thread_;
  std::atomic<bool> quit_{false};
};

// A rig file as the commands read it (nodes::readRigFile): a file in the one-muscle form ([sensor],
// [valve]) gets one notice on stderr per run that it reads as one channel and the form of slaves and
// channels replaces it.
nodes::RigFile readRig(const std::string& path);

void printStats(const nodes::CycleStats& s, const TrackingSummary& t);
// A line per joint: its angle's tracking, from its flexor's (channel's) tracking through the lever.
void printJoints(const std::vector<nodes::RigJoint>& joints, const TrackingSummary& t);

// Opens the interface with a hint on what to do when it is not there.
std::unique_ptr<canopen::SocketCanTransport> openCan(const std::string& iface);

// --od: the folder with controller.eds, sensor.eds and valve.eds.
// The EDS folder: ./od when it is there (the source tree), else the one installed with pamc
// (<prefix>/share/pamc/od next to <prefix>/bin/pamc), else the source tree's seen from the build tree.
std::string defaultOdDir();

struct OdOption {
  std::string dir = defaultOdDir();
  void add(CLI::App* a);
};

// What decode and monitor read the bus through: the rig file's devices (--rig: its slaves, COB-IDs and
// scaling) with the PDOs of the further EDS files (--eds) beside them, or the EDS files of --od and --eds.
struct BusDictionaryOptions {
  std::string rig;
  std::vector<std::string> eds;
  void add(CLI::App* a);
  nodes::BusDictionary load(const OdOption& od) const;
};

// The emulator nodes: plant, fault injection, payload (rig, emulator).
struct EmulatorOptions {
  std::string plant_file, payload;
  bool profile_defaults = false;
  nodes::EmulatorConfig ec;
  void add(CLI::App* a);
  // The emulator's configuration for the EDS folder and the SYNC period (0: 1 ms).
  nodes::EmulatorConfig config(const std::string& od_dir, unsigned period_us) const;
};

// Real-time scheduling, the same options wherever a node runs on the wall clock (controller, emulator,
// rig run): --realtime (what it does besides the scheduling: `what`), --cpu, --priority.
struct RealtimeOptions {
  bool rt = false;
  int cpu = -1, priority = 80;
  // new_path: the command the notice of the old --rt names (default: a's own).
  void add(CLI::App* a, const std::string& what, const std::string& new_path = "");
};

// --iface: the CAN interface; default: the rig file's (controller, monitor with --rig), else the one a rig
// file without `interface` means (nodes::kDefaultInterface).
struct InterfaceOption {
  std::string name;
  void add(CLI::App* a, bool with_rig = true);
  std::string resolve(const std::string& rig_file) const;
};

// The name the in-process bus of `pamc rig run --realtime` has in its candump log.
inline constexpr const char* kInProcessBusName = "vcan0";

}  // namespace pamc::app
