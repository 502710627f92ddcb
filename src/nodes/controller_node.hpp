// The pamc controller as a CANopen node (od/controller.eds): NMT master of the sensor and valve
// nodes, SYNC producer (or consumer), and in the SYNC callback the whole control cycle:
//   SYNC -> RPDOs latched (position of the sensor, pressure of the valve) -> estimate -> control ->
//   valve setpoint into the TPDO, sent right after the callback.
// The valve applies the setpoint at the next SYNC (synchronous RPDO); the sensor samples at each SYNC
// and sends right after it; the controller latches that position at the following SYNC. So the
// position the controller works with at SYNC k was taken at SYNC k-1 and reflects the setpoint
// computed at SYNC k-3: the lockstep simulation models this with delay_cycles = 2.
//
// Its parameters live in the object dictionary (gains 0x2000, model 0x2001, UKF 0x2002, controller
// 0x2010, trajectory 0x2011/0x2012, safe valve voltage 0x2020, missing-PDO limit 0x2021), so they can
// be read and set over SDO. They are taken into use when the node enters Operational, or - gains,
// model, UKF, safe value and limit - by a commit (0x2003:01 = 1) at the next cycle boundary; the loop
// never reads the dictionary's parameter entries, so it never sees a half-written set.
//
// Faults (docs/CANOPEN.md, "Safe state"): every cause is polled or reported by a hook, sends its EMCY
// once per episode, and - except the warnings - puts the valve at its safe value until the causes
// have been gone for recover_s (0.5 s); then estimator and integrator restart from the safe value and
// the setpoint ramps from the measured position back to the trajectory (no output jump).
//
// The node composes (docs/ARCHITECTURE.md): a SensorDriver and a ValveDriver (each slave's boot steps,
// PDO supervision, error value and scaling), the FaultSupervisor (raise, EMCY, safe state, recovery),
// the ControlLoop that knows no CANopen (latch -> estimate -> control -> ramp), run by the SYNC callback,
// and the OdOverrides (the command line's choices in the dictionary).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/nmt_master.hpp"
#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "nodes/control_loop.hpp"
#include "nodes/controller_config.hpp"
#include "nodes/controller_parameters.hpp"
#include "nodes/cycle_stats.hpp"
#include "nodes/fault_supervisor.hpp"
#include "nodes/faults.hpp"
#include "nodes/od_overrides.hpp"
#include "nodes/process_data.hpp"
#include "nodes/sensor_driver.hpp"
#include "nodes/valve_driver.hpp"

namespace pamc::nodes {

// What the fault handling and the parameter guard did (read from the thread that runs the node).
struct FaultCounters {
  std::uint64_t episodes = 0;  // entries into the safe state
  std::uint64_t recoveries = 0;
  std::uint64_t safe_cycles = 0;      // cycles that sent the safe value
  std::uint64_t samples_missing = 0;  // cycles after activation without a usable position
  std::uint64_t positions = 0;        // usable positions latched (0 at the end of a run: it never had one)
  std::uint64_t warnings = 0;         // warning EMCYs sent
  std::uint64_t nmt_starts = 0;       // NMT start to a slave after its boot-up or in Pre-operational
  std::uint64_t nmt_reboots = 0;      // NMT reset communication to a slave back after a heartbeat timeout
  std::uint64_t slave_boots = 0;      // slaves checked and configured at their boot
  std::uint64_t slave_boot_failures = 0;
  std::uint64_t valve_holds = 0;  // valve sent to Pre-operational (it outputs its error value)
  std::uint64_t collisions = 0;   // frames on this node's own identifiers
  std::uint32_t last_collision_cob = 0;
  std::uint64_t sets_applied = 0;  // parameter sets taken into use (NMT start or commit)
  std::uint64_t sets_refused = 0;
  std::uint64_t valve_sdo_errors =
      0;  // writing a changed safe value into the valve's 0x6444:01 failed (in its boot: a boot failure)
};

class ControllerNode {
 public:
  // clock: microseconds on the same time base the node is advanced with (for latency).
  ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                 std::function<canopen::TimeUs()> clock);
  canopen::Node& node() { return *node_; }

  // Boot-up, then Operational (unless 0x1F80 bit 2 says to wait for an NMT start); the slaves are booted
  // (checked, configured) and started, and again whenever one boots.
  void start(canopen::TimeUs now);

  // Safe to call from another thread (the command line's watcher). Of a node with several channels:
  // the first channel's fault that is not None, channel 1's trajectory time, the sum of the counters.
  Fault fault() const noexcept;
  const CycleStats& stats() const noexcept { return stats_; }
  // Every channel's cycle records, CycleRecord::channel telling them apart.
  SpscRing<CycleRecord, 1 << 15>& records() noexcept { return records_; }
  bool running() const noexcept;                                     // every channel past its pre-roll
  double runTime() const noexcept { return ch(0).loop->runTime(); }  // trajectory seconds so far; any thread
  std::uint64_t faultsRaised() const noexcept;
  control::Kind kind() const noexcept { return ch(0).loop->kind(); }
  const RangeWatch& rangeWatch(std::size_t c = 0) const noexcept { return ch(c).loop->rangeWatch(); }  // any thread
  FaultCounters faultCounters() const noexcept;  // the channels' counters summed, and the node's own
  // Channel c's share of faultCounters(): episodes, recoveries, safe cycles, warnings, samples missing,
  // positions, valve SDO errors (the node's own counters 0).
  FaultCounters channelCounters(std::size_t c) const noexcept;
  // Causes whose EMCY went out in the present episode (bit per Fault), of every channel.
  std::uint32_t episodeCauses() const noexcept;
  // The channels: how many, and each one's fault (any thread).
  std::size_t channels() const noexcept { return channels_.size(); }
  Fault channelFault(std::size_t c) const noexcept { return ch(c).faults->published(); }
  // The parameters the loop uses (kp, ki, ... as taken into use).
  const control::ControllerConfig& activeParameters() const noexcept { return params_->running().ctrl; }
  double safeCommand() const noexcept { return params_->safeCommand(); }  // relative volts (-5 = 0 V)
  std::uint32_t lastRefusal() const noexcept {
    return params_->lastRefusal();
  }  // abort code of the last refused commit
  // COB-ID of the last frame another node sent on this node's identifiers (0: none); any thread.
  std::uint32_t lastCollisionCob() const noexcept { return collision_pub_.load(std::memory_order_relaxed); }
  // COB-ID channel 1's position is awaited on (as configured at the last NMT start); any thread.
  std::uint32_t positionCob() const noexcept { return ch(0).sensor->cob(); }
  std::uint8_t sensorId() const noexcept { return ch(0).sensor->id(); }
  double noPositionSeconds() const noexcept { return ch(0).sensor->noPositionSeconds(); }
  // Node time of the first reaction (EMCY or safe state) of the present episode; kNever if none.
  canopen::TimeUs reactedAtUs() const noexcept;
  canopen::TimeUs reactedAtUs(std::size_t c) const noexcept { return ch(c).faults->reactedAt(); }  // channel c's
  const canopen::NmtMaster& master() const noexcept { return *master_; }
  const pd::Scaling& scaling() const noexcept { return ch(0).sensor->scaling(); }

 private:
  // One channel: its input and output drivers, its faults, its loop.
  struct Channel {
    std::unique_ptr<SensorDriver> sensor;
    std::unique_ptr<ValveDriver> valve;
    std::unique_ptr<FaultSupervisor> faults;
    std::unique_ptr<ControlLoop> loop;
    int partner = -1;
    double offset_v = 0.0;            // a joint's co-contraction on the loop's command
    SensorDriver::Sample sample;      // latched at this SYNC
    CycleRecord rec;                  // this cycle's, to the ring after the TPDO
    double command() const noexcept;  // what the valve gets
  };
  const Channel& ch(std::size_t c) const noexcept { return channels_[c]; }
  void addChannel(const ControllerNodeConfig& cfg, std::size_t c);
  std::unique_ptr<control::Controller> buildFor(control::Kind kind, const control::ControllerConfig& ctrl,
                                                std::size_t c) const;
  void installHooks();
  void installStateHook();
  void configureFromOd();
  void onOperational(canopen::TimeUs now);
  void takeCommitted() noexcept;

  // The cycle, in the order onSync runs it: each channel's input, the faults (a channel's spreading
  // to its partner), each channel's loop, each channel's output.
  void onSync(std::uint8_t counter, canopen::TimeUs now) noexcept;
  void measurePeriod(canopen::TimeUs now) noexcept;
  void input(Channel& c) noexcept;
  void poll(Channel& c, canopen::TimeUs now) noexcept;
  void spreadFaults() noexcept;
  void control(Channel& c, canopen::TimeUs now) noexcept;
  void send(Channel& c, std::uint8_t number, double latency_us) noexcept;

  // Faults: the supervisor's causes, and on entering the safe state the valve at its safe value.
  void raiseAll(Fault f, std::uint8_t detail = 0) noexcept;
  void takeCauses(Channel& c, canopen::TimeUs now) noexcept;
  void recover(Channel& c, double y, canopen::TimeUs now) noexcept;
  void onSlaveEvent(std::uint8_t id, canopen::SlaveEvent ev);
  void logSlaveEvent(const char* role, std::uint8_t id, canopen::SlaveEvent ev) const;
  void holdValves(std::uint8_t reason) noexcept;
  void releaseValves(std::uint8_t reason, canopen::TimeUs now) noexcept;

  std::function<canopen::TimeUs()> clock_;
  std::unique_ptr<canopen::Node> node_;
  std::unique_ptr<canopen::NmtMaster> master_;  // of the sensors and the valves
  std::unique_ptr<OdOverrides> overrides_;
  std::unique_ptr<ControllerParameters> params_;  // the dictionary's parameter set and its commit
  std::vector<Channel> channels_;
  std::vector<ChannelConfig> channel_cfg_;  // what each channel runs of its own
  std::vector<std::string> governor_said_;  // the MBC governor's note each channel last gave (said once)
  bool fault_all_ = false;
  std::function<void(const std::string&)> log_;  // the slaves' boot reports
  std::uint64_t collisions_ = 0;                 // frames on this node's own identifiers
  std::atomic<std::uint32_t> collision_pub_{0};
  canopen::TimeUs last_sync_ = 0;
  CycleStats stats_;
  SpscRing<CycleRecord, 1 << 15> records_;
};

}  // namespace pamc::nodes
