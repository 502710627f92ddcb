// Faults on the bus, one at a time, on the in-process rig in virtual time (deterministic, seeded):
// the controller, sensor and valve nodes of the rig plus whatever the fault needs on the bus (a SYNC
// producer that stops, a node flooding the bus with high-priority frames, a second node with the
// same node-ID, injected error frames). Each run tracks a trajectory, injects the fault after 3 s of
// the trajectory, clears it, and measures what the controller did: cycles until it detected the
// fault and until the valve output its safe value, the EMCY codes on the bus, whether and how
// smoothly control resumed, and what was lost. `pamc rig faults` prints the table
// (docs/RELIABILITY.md); tests/unit/test_faults.cpp checks each row. On a rig file of several channels
// (`--rig`) the faults of the sensor hit one channel's (`--channel`), and the table adds what the other
// channels did (tests/unit/test_faults_per_channel.cpp).
//
// Also here: the parameter guard of the controller over SDO, write by write (`pamc rig guards`).
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "canopen/service.hpp"
#include "control/controller.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/rig_file.hpp"

namespace pamc::rig {

enum class BusFault {
  None,                  // the reference run
  SensorSilentShort,     // sensor sends nothing for 100 ms
  SensorSilentLong,      // ... for 1 s (its heartbeat times out)
  SensorReboot,          // sensor off for 50 ms, then boot-up and Pre-operational
  PdoLateInCycle,        // position PDOs 0.9 periods late (after the synchronous window) for 200 ms
  PdoLateCycle,          // position PDOs 1.2 periods late (in the next cycle's window) for 2 s
  PdoDropRandom,         // 5 % of the position PDOs dropped at random for 2 s
  PdoDropBurst,          // 10 position PDOs in a row dropped
  PdoDuplicate,          // every position PDO sent twice for 2 s
  SyncStop,              // the SYNC producer (another node; the controller consumes) stops for 100 ms
  ValveSilentShort,      // valve sends nothing for 100 ms
  ValveSilentLong,       // ... for 1 s
  FloodHalf,             // 1 Mbit/s bus, 50 % load of 8-byte frames with identifier 0x010 for 2 s
  FloodFull,             // ... 100 % (babbling node) for 200 ms
  PdoShortOnce,          // one position PDO with 3 instead of 4 bytes
  PdoLong,               // position PDOs with 8 bytes for 200 ms
  SyncWrongLength,       // SYNC with 1 data byte (0x1019 = 0: none) for 100 ms; the controller consumes
  HeartbeatWrongLength,  // sensor heartbeats with 2 bytes for 1 s
  DuplicateController,   // a second node with node-ID 1 (boot-up, heartbeats) for 1 s
  DuplicateSensor,       // a second node with node-ID 2 (heartbeats, position PDOs) for 1 s
  ErrorPassive,          // CAN error frame: controller error passive, error active again 100 ms later
  BusOff,                // CAN error frame: bus off, restarted 100 ms later
  CanOverflow,           // CAN error frame: controller receive overflow
  // Injected before the controller starts (the loop has never run):
  SensorPdoMovedAtStart,  // the sensor's position TPDO on COB-ID 0x190 when the controller starts, 2 s
};

std::vector<BusFault> allBusFaults();
std::vector<BusFault> runningBusFaults();  // those injected into a running loop (the soak draws from them)
const char* busFaultName(BusFault f);      // short name for --only
std::string busFaultDescription(BusFault f);

struct FaultRigOptions {
  std::string od_dir = "od";
  control::Kind kind = control::Kind::PiAmc;
  double kp = control::kDefaultGains.kp, ki = control::kDefaultGains.ki, kc = control::kDefaultGains.kc;
  double preroll_s = 1.0;
  double inject_at_s = 3.0;  // trajectory time of the injection
  double after_s = 8.0;      // run on this long after the fault cleared
  std::uint64_t seed = 7;
  // A rig file of several channels (docs/RIG.md, "Several muscles") to run instead of the built-in
  // one-muscle layout, played by rig::emulatorOf's devices; the faults of "the sensor" hit the sensor of
  // `channel` (0-based), those of the valve module, the SYNC and the bus what every channel shares.
  std::optional<nodes::RigFile> rig;
  std::size_t channel = 0;
};

struct FaultRun {
  BusFault fault = BusFault::None;
  double fault_s = 0;                       // how long the fault was injected
  nodes::Fault first = nodes::Fault::None;  // the controller's first safety fault (None: it stayed in control)
  double detect_cycles = -1;                // SYNC periods from the injection to the controller's reaction (-1: none)
  double safe_cycles = -1;                  // ... until the valve output its safe value (-1: it did not)
  std::vector<std::uint16_t> emcy;          // EMCY codes the controller sent after the injection, in order
  bool emcy_reset = false;                  // an EMCY error reset (0x0000) followed
  bool recovered = false;                   // no fault at the end and control running
  double resume_s = -1;                   // from the end of the injection until control resumed (-1: it never stopped)
  double max_step_v = 0;                  // largest |u_k - u_k-1| in the first 3 s of control after the fault
  double step_before_v = 0;               // ... in the second before the injection (for comparison)
  std::uint64_t samples_lost = 0;         // cycles the controller had no usable position
  std::uint64_t cycles_without_sync = 0;  // SYNC periods in which no control cycle ran
  canopen::Counters counters;             // the controller node's counters at the end
  nodes::FaultCounters fc;
  std::uint64_t bus_dropped = 0;  // frames the in-process bus refused (port queue full)
  // The channels (one without a rig file): the figures above are of `channels.faulted` (0-based), the one
  // the row faulted; these of each channel, index the channel.
  struct Channels {
    std::size_t faulted = 0;
    std::vector<double> rmse_end, rmse_base;  // tracking RMSE over the last 2 s, and of the reference run [mm]
    // RMSE from the injection to 1 s after the fault cleared, and the same window of the reference run [mm].
    std::vector<double> rmse_fault, rmse_fault_base;
    std::vector<std::uint64_t> safe_cycles;  // cycles it sent the safe value after the injection
    // The channels the EMCYs after the injection named (1-based, ascending; 0: a node of one channel names none).
    std::vector<std::uint8_t> emcy_named;
  } channels;
  // The row's channel's: its RMSE of the last 2 s and the reference run's [mm], its cycles at the safe value.
  double rmseEnd() const noexcept { return at(channels.rmse_end); }
  double rmseBase() const noexcept { return at(channels.rmse_base); }
  std::uint64_t safeCyclesTotal() const noexcept {
    return channels.faulted < channels.safe_cycles.size() ? channels.safe_cycles[channels.faulted] : 0;
  }

 private:
  double at(const std::vector<double>& v) const noexcept {
    return channels.faulted < v.size() ? v[channels.faulted] : std::numeric_limits<double>::quiet_NaN();
  }
};

// One run with the fault (and its reference run without it).
FaultRun runBusFault(BusFault f, const FaultRigOptions& o = {});
// Runs the faults given (all if empty) and returns them in order.
std::vector<FaultRun> runFaultTable(const std::vector<BusFault>& faults, const FaultRigOptions& o = {});
// Markdown table: fault, reaction, cycles to safe state, EMCY, recovered, data lost. Runs of several
// channels add the channels the EMCYs named and what the other channels did (worst RMSE of the last 2 s
// against its own reference run, which of them went to the safe value).
std::string faultTableMarkdown(const std::vector<FaultRun>& runs);

// Soak: one long run of the rig in virtual time with faults of the catalogue injected one after the
// other at random times (seeded), checking that nothing degrades over the hours: memory (heap in use,
// RSS), the cycle (one control cycle per SYNC period outside faults, no record lost, CPU time per
// cycle), and tracking after every fault (RMSE over one trajectory period after control is back,
// against the no-fault baseline of the same run). `pamc rig soak --hours HOURS`.
//
// The rig is set up for every fault at once: the controller consumes the SYNC of a separate producer
// (so that SYNC faults can be injected), the bus has 1 Mbit/s bit timing with arbitration (for the
// floods), and a second node-ID 1 and 2 sit idle on the bus until injected.
struct SoakOptions {
  std::string od_dir = "od";
  control::Kind kind = control::Kind::PiAmc;
  double kp = control::kDefaultGains.kp, ki = control::kDefaultGains.ki, kc = control::kDefaultGains.kc;
  double hours = 24.0;                       // simulated time in total
  double report_s = 3600.0;                  // one report line per this much simulated time
  std::uint64_t seed = 1;                    // fault times and choices, sensor noise
  std::vector<BusFault> faults;              // the catalogue to draw from (empty: all)
  double gap_min_s = 5.0, gap_max_s = 30.0;  // clean time between a fault's check and the next injection
  double warmup_s = 20.0;                    // trajectory time before the baseline is taken
  int baseline_periods = 4;                  // trajectory periods (5 s) averaged for the no-fault baseline
  double settle_s = 6.0;                     // after control is back, before the check period starts
  double tolerance = 0.25;                   // check: RMSE <= baseline * (1 + tolerance) + 0.005 mm
  double resume_limit_s = 30.0;              // control must be back this long after the fault ended
  double heap_growth_limit = 64 * 1024.0;    // bytes of heap growth allowed after the first report
  double cpu_drift_limit = 1.5;              // CPU per cycle, last third of the reports over the first third
};

struct SoakInterval {
  // Between faults: the trajectory periods without a fault.
  struct Clean {
    double rmse_mean = 0, rmse_max = 0;  // their RMSE [mm]
    std::uint64_t periods = 0;
    std::uint64_t bad = 0;  // ... of them above the tolerance (tracking left its level without a fault)
  };
  // What the run cost the machine.
  struct Usage {
    double heap_mb = 0, rss_mb = 0;           // at the end of the interval
    double cpu_us_per_cycle = 0;              // process CPU time per SYNC period of the interval
    double step_us_p99 = 0, step_us_max = 0;  // wall time of one 1 ms step of the whole rig
    double wall_s = 0;                        // wall time of the interval
  };
  int index = 0;
  double end_h = 0;                     // simulated hours at the end of the interval
  std::uint64_t cycles = 0;             // control cycles run
  std::uint64_t syncs = 0;              // SYNCs the producer sent
  std::uint64_t missed_syncs = 0;       // SYNC gaps the controller counted (SYNC faults)
  std::uint64_t lost_clean = 0;         // periods outside faults without exactly one control cycle
  std::uint64_t ring_dropped = 0;       // cycle records lost in the ring (the soak drains every period)
  std::uint64_t faults = 0;             // faults injected in the interval
  std::uint64_t reacted = 0;            // ... that put the controller in its safe state
  std::uint64_t checked = 0, back = 0;  // tracking checks done, and passed
  double worst_ratio = 0;               // largest check RMSE / baseline
  Clean clean;
  std::uint64_t safe_cycles = 0, samples_missing = 0;  // the controller's counters over the interval
  std::uint64_t emcy = 0;                              // EMCY frames (with resets)
  Usage usage;
};

struct SoakFaultStat {
  BusFault fault = BusFault::None;
  std::uint64_t injected = 0, reacted = 0, checked = 0, back = 0;
  double worst_ratio = 0, max_resume_s = 0;
};

struct SoakResult {
  std::vector<SoakInterval> intervals;
  std::vector<SoakFaultStat> per_fault;  // in catalogue order, faults drawn at least once
  std::vector<std::string> failures;     // the first 50, one line each
  std::uint64_t failure_count = 0;
  double baseline_rmse = 0;  // mm, over baseline_periods trajectory periods before any fault
  std::uint64_t faults = 0, reacted = 0, checked = 0, back = 0;
  double heap_growth_bytes = 0;  // last report minus first report
  double rss_growth_mb = 0;
  double cpu_drift = 0;  // ratio, see cpu_drift_limit
  bool memory_ok = true, cycle_ok = true, tracking_ok = true, timing_ok = true;
  bool passed() const { return memory_ok && cycle_ok && tracking_ok && timing_ok; }
  double wall_s = 0;
  bool asan = false;  // heap figures from AddressSanitizer's allocator
};

// Runs the soak; on_interval (if set) sees each report line as it completes, on_progress every
// simulated minute (simulated seconds so far).
SoakResult runSoak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval = {},
                   const std::function<void(double)>& on_progress = {});
std::string soakIntervalHeader();
std::string soakIntervalLine(const SoakInterval& i);
// The whole report: per-interval table (unless intervals is false), per-fault table, memory, cycle and
// tracking summary, failures, verdict.
std::string soakReport(const SoakOptions& o, const SoakResult& r, bool intervals = true);

// The parameter guard: SDO writes to the running controller and what became of them.
struct GuardRow {
  std::string write;       // what was written, and in which state
  std::uint32_t expected;  // abort code expected (0: accepted)
  std::uint32_t got;
  std::string effect;  // what the loop saw
};
std::vector<GuardRow> runParameterGuards(const FaultRigOptions& o = {});
std::string guardTableMarkdown(const std::vector<GuardRow>& rows);

}  // namespace pamc::rig
