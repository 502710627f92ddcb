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
#include <string>

#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "nodes/cycle_stats.hpp"
#include "nodes/faults.hpp"
#include "sim/trajectory.hpp"

namespace pamc::nodes {


struct ControllerNodeConfig {
  std::string eds_path = "od/controller.eds";
  // Overrides of the object dictionary's defaults (unset: the EDS value).
  int kind = -1;                      // control::Kind
  control::ControllerConfig ctrl;     // the model (and, with gains_from_config, the gains)
  bool gains_from_config = false;     // write ctrl's gains into the OD instead of reading them
  // Cycles from a command to the position that shows it, beyond one sample: 2 with this node's
  // timing (a synchronous valve RPDO, a sensor sending right after the SYNC); other slaves may differ.
  int delay_cycles = 2;
  bool has_trajectory = false;
  sim::Trajectory trajectory;
  double preroll_s = 5.0;             // hold the first setpoint this long before the trajectory starts
  bool produce_sync = true;
  unsigned period_us = 0;             // SYNC period override (0: 0x1006 of the EDS)
  std::uint8_t sensor_id = 2, valve_id = 3;
  int recover_cycles = 500;           // a fault must be gone this long before control resumes
  double ramp_mm_per_s = 10.0;        // after recovery or a commit the setpoint returns at most this fast
  double ramp_slew_v = 0.02;          // ... and the command changes at most this much per cycle [V]
};

// What the fault handling and the parameter guard did (read from the thread that runs the node).
struct FaultCounters {
  std::uint64_t episodes = 0;         // entries into the safe state
  std::uint64_t recoveries = 0;
  std::uint64_t safe_cycles = 0;      // cycles that sent the safe value
  std::uint64_t samples_missing = 0;  // cycles after activation without a usable position
  std::uint64_t warnings = 0;         // warning EMCYs sent
  std::uint64_t nmt_starts = 0;       // NMT start to a slave after its boot-up or in Pre-operational
  std::uint64_t nmt_reboots = 0;      // NMT reset communication to a slave back after a heartbeat timeout
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

  // Boot-up, then Operational; NMT start to both slaves (and again whenever one boots).
  void start(canopen::TimeUs now);

  // Safe to call from another thread (the command line's watcher).
  Fault fault() const noexcept { return fault_pub_.load(std::memory_order_relaxed); }
  const CycleStats& stats() const noexcept { return stats_; }
  SpscRing<CycleRecord, 1 << 15>& records() noexcept { return records_; }
  bool running() const noexcept { return run_started_; }
  double runTime() const noexcept { return run_time_pub_.load(std::memory_order_relaxed); }  // trajectory seconds so far; any thread
  std::uint64_t faultsRaised() const noexcept { return faults_raised_; }
  control::Kind kind() const noexcept { return kind_; }
  const FaultCounters& faultCounters() const noexcept { return fc_; }
  // Causes whose EMCY went out in the present episode (bit per Fault).
  std::uint32_t episodeCauses() const noexcept { return episode_; }
  // The parameters the loop uses (kp, ki, ... as taken into use).
  const control::ControllerConfig& activeParameters() const noexcept { return running_.ctrl; }
  double safeCommand() const noexcept { return safe_u_; }  // relative volts (-5 = 0 V)
  std::uint32_t lastRefusal() const noexcept { return last_refusal_; }  // abort code of the last refused commit
  // COB-ID of the last frame another node sent on this node's identifiers (0: none); any thread.
  std::uint32_t lastCollisionCob() const noexcept { return collision_pub_.load(std::memory_order_relaxed); }
  // Node time of the first reaction (EMCY or safe state) of the present episode; kNever if none.
  canopen::TimeUs reactedAtUs() const noexcept { return reacted_at_us_; }

 private:
  struct Params {
    control::ControllerConfig ctrl;
    double safe_u = -5.0;
    unsigned missing_limit = 3;
    double range_steps = 100000;        // 0x2022:01
    double stuck_s = 0.25;              // 0x2022:02
    double stuck_span_v = 1.0;          // 0x2022:03 (0: off)
  };
  // 0x2022 by sub-index 1..3.
  static constexpr double Params::*kPlausibility[] = {&Params::range_steps, &Params::stuck_s, &Params::stuck_span_v};
  struct Slave {
    std::uint8_t id = 0;
    bool lost = false;                          // heartbeat timed out: re-boot it when it is back
    canopen::TimeUs start_sent = canopen::kNever;  // NMT start sent, no Operational heartbeat yet
  };
  enum : std::uint8_t { kHoldSync = 1, kHoldCollision = 2, kHoldSelf = 4 };

  void applyOverrides();
  void installGuards();
  Params readParams();
  void writeParams(const Params& p);
  // kSdoOk or the abort code refusing the set; why names the entry or the condition.
  std::uint32_t checkParams(const Params& p, std::string* why);
  void configureFromOd();
  std::uint32_t commit();
  void discard();
  void takeCommitted(double y) noexcept;

  void onSync(std::uint8_t counter, canopen::TimeUs now) noexcept;
  void poll(canopen::TimeUs now, bool usable) noexcept;  // usable: a plausible position arrived
  void raise(Fault f, std::uint8_t detail = 0) noexcept;
  void takeCauses(canopen::TimeUs now) noexcept;
  void recover(double y, canopen::TimeUs now) noexcept;
  void onHeartbeatEvent(std::uint8_t id, canopen::HeartbeatEvent ev, canopen::NmtState st, canopen::TimeUs now) noexcept;
  void onErrorFrame(const canopen::Frame& f) noexcept;
  bool slaveDown(Slave& s, canopen::TimeUs now) noexcept;
  void startSlave(Slave& s, canopen::TimeUs now) noexcept;
  void hold(std::uint8_t reason) noexcept;
  void release(std::uint8_t reason, canopen::TimeUs now) noexcept;
  void pushValveErrorValue() noexcept;
  void startRamp(double y) noexcept;
  double setpoint(double t, int ahead) const noexcept;

  ControllerNodeConfig cfg_;
  std::function<canopen::TimeUs()> clock_;
  std::unique_ptr<canopen::Node> node_;
  std::unique_ptr<control::Controller> ctrl_;
  control::Kind kind_ = control::Kind::PI;
  sim::Trajectory traj_;
  double Ts_ = 1e-3;
  double safe_u_ = -5.0;
  unsigned missing_limit_ = 3;
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
  std::uint64_t config_errors_ = 0;
  bool traj_override_ = false;
  double last_u_ = -5.0;
  // NMT master
  Slave sensor_, valve_;
  std::uint8_t hold_ = 0;       // reasons the valve is kept Pre-operational
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
  // Bumpless return: the setpoint goes from ramp_from_ to the trajectory over ramp_cycles_.
  bool ramp_ = false;
  bool slew_ = false;           // command rate-limited: during the ramp and until the limit no longer binds
  double ramp_from_ = 0.0;
  std::uint64_t ramp_k0_ = 0, ramp_cycles_ = 1;
  // Parameter sets: the one in use, and a committed one the next SYNC takes.
  Params running_, next_;
  std::unique_ptr<control::Controller> next_ctrl_;
  std::unique_ptr<control::Controller> retired_;  // replaced at a cycle boundary, freed at the next commit
  bool commit_ready_ = false;
  canopen::Ref<std::uint8_t> staged_flag_{nullptr};
  canopen::Ref<std::uint8_t> sets_applied_{nullptr};
  std::uint32_t last_refusal_ = 0;
  FaultCounters fc_;
  std::atomic<Fault> fault_pub_{Fault::None};
  std::atomic<double> run_time_pub_{0.0};
  std::atomic<std::uint32_t> collision_pub_{0};
  canopen::TimeUs last_sync_ = 0;
  CycleStats stats_;
  SpscRing<CycleRecord, 1 << 15> records_;
};

}  // namespace pamc::nodes
