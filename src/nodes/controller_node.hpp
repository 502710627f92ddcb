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
// have been gone for recover_cycles; then estimator and integrator restart from the safe value and
// the setpoint ramps from the measured position back to the trajectory (no output jump).
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "canopen/nmt_master.hpp"
#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "nodes/controller_parameters.hpp"
#include "nodes/cycle_stats.hpp"
#include "nodes/faults.hpp"
#include "nodes/process_data.hpp"
#include "control/trajectory.hpp"

namespace pamc::nodes {

// The slaves as a rig file describes them (nodes/rig_file.hpp); the defaults are pamc's own devices
// with the layout of od/*.eds, which need no configuration.
struct SlaveLayout {
  pd::Scaling scaling;
  std::uint32_t sensor_cob = 0;    // COB-ID of the sensor's position PDO (0: the controller EDS's 0x1400:01)
  std::uint32_t valve_cob = 0;     // COB-ID of the valve's command PDO (0: 0x1800:01)
  std::uint32_t feedback_cob = 0;  // COB-ID of the valve's feedback PDO (0: 0x1401:01)
  bool feedback = true;            // the valve sends its pressure; its absence is a fault
  // The valve's error value (CiA 401 0x6444:n for the output 0x6411:n); index 0: none to write.
  std::uint16_t error_value_index = 0x6444;
  std::uint8_t error_value_sub = 1;
  // Boot of the slaves (NMT master, canopen/nmt_master.hpp): identity check and configuration.
  std::optional<canopen::SlaveBoot> sensor_boot, valve_boot;
  bool position_step_from_device = false;  // the step is read from the sensor at its boot (0x6005:01, nm)
  std::uint32_t startup = 0;               // 0x1F80 (0: the EDS's)
};

struct ControllerNodeConfig {
  std::string eds_path = "od/controller.eds";
  std::uint8_t node_id = 0;           // 0: the EDS's
  // Overrides of the object dictionary's defaults (unset: the EDS value).
  int kind = -1;                      // control::Kind
  control::ControllerConfig ctrl;     // the model (and, with gains_from_config, the gains)
  bool gains_from_config = false;     // write ctrl's gains into the OD instead of reading them
  // Cycles from a command to the position that shows it, beyond one sample: 2 with this node's
  // timing (a synchronous valve RPDO, a sensor sending right after the SYNC); other slaves may differ.
  int delay_cycles = 2;
  bool has_trajectory = false;
  control::Trajectory trajectory;
  double preroll_s = 5.0;             // hold the first setpoint this long before the trajectory starts
  bool produce_sync = true;
  unsigned period_us = 0;             // SYNC period override (0: 0x1006 of the EDS)
  std::uint8_t sensor_id = 2, valve_id = 3;
  int recover_cycles = 500;           // a fault must be gone this long before control resumes
  double ramp_mm_per_s = 10.0;        // after recovery or a commit the setpoint returns at most this fast
  double ramp_slew_v = 0.02;          // ... and the command changes at most this much per cycle [V]
  double no_position_s = 1.0;         // no position this long after entering Operational: Fault::NoPosition
  SlaveLayout layout;
  // The controller of an SDO commit built on a worker thread instead of in the SDO server (on a rig; in
  // virtual time the inline build keeps runs deterministic). docs/PERFORMANCE.md has what it saves.
  bool build_off_cycle = false;
  // Boot reports of the slaves (configured, or why not); called on the node's thread, outside the cycle.
  std::function<void(const std::string&)> log;
};

// What the fault handling and the parameter guard did (read from the thread that runs the node).
struct FaultCounters {
  std::uint64_t episodes = 0;         // entries into the safe state
  std::uint64_t recoveries = 0;
  std::uint64_t safe_cycles = 0;      // cycles that sent the safe value
  std::uint64_t samples_missing = 0;  // cycles after activation without a usable position
  std::uint64_t positions = 0;        // usable positions latched (0 at the end of a run: it never had one)
  std::uint64_t warnings = 0;         // warning EMCYs sent
  std::uint64_t nmt_starts = 0;       // NMT start to a slave after its boot-up or in Pre-operational
  std::uint64_t nmt_reboots = 0;      // NMT reset communication to a slave back after a heartbeat timeout
  std::uint64_t slave_boots = 0;      // slaves checked and configured at their boot
  std::uint64_t slave_boot_failures = 0;
  std::uint64_t valve_holds = 0;      // valve sent to Pre-operational (it outputs its error value)
  std::uint64_t collisions = 0;       // frames on this node's own identifiers
  std::uint32_t last_collision_cob = 0;
  std::uint64_t sets_applied = 0;     // parameter sets taken into use (NMT start or commit)
  std::uint64_t sets_refused = 0;
  std::uint64_t valve_sdo_errors = 0;  // writing the safe value into the valve's 0x6444:01 failed
};

class ControllerNode {
 public:
  // clock: microseconds on the same time base the node is advanced with (for latency).
  ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport, std::function<canopen::TimeUs()> clock);
  canopen::Node& node() { return *node_; }

  // Boot-up, then Operational (unless 0x1F80 bit 2 says to wait for an NMT start); the slaves are booted
  // (checked, configured) and started, and again whenever one boots.
  void start(canopen::TimeUs now);

  // Safe to call from another thread (the command line's watcher).
  Fault fault() const noexcept { return fault_pub_.load(std::memory_order_relaxed); }
  const CycleStats& stats() const noexcept { return stats_; }
  SpscRing<CycleRecord, 1 << 15>& records() noexcept { return records_; }
  bool running() const noexcept { return run_started_; }
  double runTime() const noexcept { return run_time_pub_.load(std::memory_order_relaxed); }  // trajectory seconds so far; any thread
  std::uint64_t faultsRaised() const noexcept { return faults_raised_; }
  control::Kind kind() const noexcept { return kind_; }
  FaultCounters faultCounters() const noexcept;
  // Causes whose EMCY went out in the present episode (bit per Fault).
  std::uint32_t episodeCauses() const noexcept { return episode_; }
  // The parameters the loop uses (kp, ki, ... as taken into use).
  const control::ControllerConfig& activeParameters() const noexcept { return params_->running().ctrl; }
  double safeCommand() const noexcept { return params_->safeCommand(); }  // relative volts (-5 = 0 V)
  std::uint32_t lastRefusal() const noexcept { return params_->lastRefusal(); }  // abort code of the last refused commit
  // COB-ID of the last frame another node sent on this node's identifiers (0: none); any thread.
  std::uint32_t lastCollisionCob() const noexcept { return collision_pub_.load(std::memory_order_relaxed); }
  // COB-ID the position is awaited on (RPDO1, as configured at the last NMT start); any thread.
  std::uint32_t positionCob() const noexcept { return position_cob_pub_.load(std::memory_order_relaxed); }
  std::uint8_t sensorId() const noexcept { return cfg_.sensor_id; }
  double noPositionSeconds() const noexcept { return cfg_.no_position_s; }
  // Node time of the first reaction (EMCY or safe state) of the present episode; kNever if none.
  canopen::TimeUs reactedAtUs() const noexcept { return reacted_at_us_; }
  const canopen::NmtMaster& master() const noexcept { return *master_; }
  const pd::Scaling& scaling() const noexcept { return scaling_; }

 private:
  // Reasons the valve is held in Pre-operational, where it outputs its error value.
  enum : std::uint8_t { kHoldSync = 1, kHoldCollision = 2, kHoldSelf = 4 };
  // The position latched at a SYNC.
  struct Sample {
    std::int32_t raw = 0;
    double y = 0.0;       // [mm]
    double y_ctrl = 0.0;  // what the controller gets: y, or NaN outside the measuring range
    bool fresh = false;   // it arrived in the last cycle
    bool in_range = false;
    bool usable() const noexcept { return fresh && in_range; }
  };

  void installHooks();
  void applyOverrides();
  void configureFromOd();
  void onOperational(canopen::TimeUs now);
  void takeCommitted(double y) noexcept;

  // The cycle, in the order onSync runs it.
  void onSync(std::uint8_t counter, canopen::TimeUs now) noexcept;
  void measurePeriod(canopen::TimeUs now) noexcept;
  Sample latch() const noexcept;
  void checkPlausibility(const Sample& s) noexcept;
  void advance(const Sample& s) noexcept;
  void poll(canopen::TimeUs now, bool usable) noexcept;
  CycleRecord control(const Sample& s, canopen::TimeUs now) noexcept;
  void clearWarnings() noexcept;
  void send(CycleRecord rec, canopen::TimeUs now) noexcept;

  // Faults.
  void raise(Fault f, std::uint8_t detail = 0) noexcept;
  void takeCauses(canopen::TimeUs now) noexcept;
  void recover(double y, canopen::TimeUs now) noexcept;
  void onSlaveEvent(std::uint8_t id, canopen::SlaveEvent ev);
  void onErrorFrame(const canopen::Frame& f) noexcept;
  void hold(std::uint8_t reason) noexcept { master_->hold(cfg_.valve_id, reason); }
  void release(std::uint8_t reason, canopen::TimeUs now) noexcept { master_->release(cfg_.valve_id, reason, now); }
  bool valveHeld() const noexcept { return master_->holdReasons(cfg_.valve_id) != 0; }
  void pushValveErrorValue() noexcept;

  // Bumpless return to the trajectory.
  void startRamp(double y) noexcept;
  double setpoint(double t, int ahead) const noexcept;
  double runSeconds() const noexcept;

  ControllerNodeConfig cfg_;
  std::function<canopen::TimeUs()> clock_;
  std::unique_ptr<canopen::Node> node_;
  std::unique_ptr<canopen::NmtMaster> master_;    // of the sensor and the valve
  std::unique_ptr<ControllerParameters> params_;  // the dictionary's parameter set and its commit
  std::unique_ptr<control::Controller> ctrl_;
  control::Kind kind_ = control::Kind::PI;
  control::Trajectory traj_;
  double Ts_ = 1e-3;
  pd::Scaling scaling_;         // set before the slaves start (a step read at the sensor's boot)
  canopen::Ref<std::int32_t> position_{nullptr};
  canopen::Ref<std::int16_t> valve_cmd_{nullptr};
  bool active_ = false;         // controller activated (valid position seen)
  bool run_started_ = false;
  std::uint64_t cycle_ = 0;     // cycles since activation
  std::uint64_t preroll_cycles_ = 0;
  Fault fault_ = Fault::None;
  std::uint32_t pending_ = 0;   // causes raised since the last cycle (bit per Fault)
  std::uint32_t episode_ = 0;   // causes whose EMCY went out in this episode
  std::uint8_t detail_[kFaultCount] = {};
  int clear_cycles_ = 0;
  int warn_clear_ = 0;
  std::uint64_t faults_raised_ = 0;
  bool traj_override_ = false;
  double last_u_ = -5.0;
  bool bus_off_ = false;
  bool push_valve_ = false;
  std::uint64_t tx_dropped_seen_ = 0, tx_expired_seen_ = 0, pdo_length_seen_ = 0, sync_length_seen_ = 0;
  int conflict_run_ = 0;
  // Plausibility of the position: positions outside the range in a row; the run of identical
  // positions and the command's span since it began.
  unsigned range_run_ = 0;
  bool have_raw_ = false;
  std::int32_t raw_last_ = 0;
  unsigned same_run_ = 0;
  double run_u_min_ = 0.0, run_u_max_ = 0.0;
  canopen::TimeUs reacted_at_us_ = canopen::kNever;
  canopen::TimeUs operational_at_ = canopen::kNever;  // entered Operational (kNever: it is not)
  // Bumpless return: the setpoint goes from ramp_from_ to the trajectory over ramp_cycles_.
  bool ramp_ = false;
  bool slew_ = false;           // command rate-limited: during the ramp and until the limit no longer binds
  double ramp_from_ = 0.0;
  std::uint64_t ramp_k0_ = 0, ramp_cycles_ = 1;
  FaultCounters fc_;
  std::atomic<Fault> fault_pub_{Fault::None};
  std::atomic<double> run_time_pub_{0.0};
  std::atomic<std::uint32_t> collision_pub_{0};
  std::atomic<std::uint32_t> position_cob_pub_{0};
  canopen::TimeUs last_sync_ = 0;
  CycleStats stats_;
  SpscRing<CycleRecord, 1 << 15> records_;
};

}  // namespace pamc::nodes
