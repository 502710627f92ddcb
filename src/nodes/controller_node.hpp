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
// be read and set over SDO; they are taken into use when the node enters Operational.
#pragma once

#include <atomic>
#include <functional>
#include <memory>
#include <string>

#include "canopen/node.hpp"
#include "control/controller.hpp"
#include "nodes/cycle_stats.hpp"
#include "sim/trajectory.hpp"

namespace pamc::nodes {

enum class Fault : std::uint8_t {
  None = 0,
  SensorHeartbeat = 1,  // no heartbeat from the sensor node
  PositionMissing = 2,  // no position PDO for the configured number of cycles
  Estimator = 3,        // non-finite command or estimate, or the UKF had to reset
  BusError = 4,         // CAN error frame (error passive, bus off, ...)
  ValveHeartbeat = 5,   // no heartbeat from the valve node
};
const char* toString(Fault f);
std::uint16_t emcyCode(Fault f);

struct ControllerNodeConfig {
  std::string eds_path = "od/controller.eds";
  // Overrides of the object dictionary's defaults (unset: the EDS value).
  int kind = -1;                      // control::Kind
  control::ControllerConfig ctrl;     // the model (and, with gains_from_config, the gains)
  bool gains_from_config = false;     // write ctrl's gains into the OD instead of reading them
  bool has_trajectory = false;
  sim::Trajectory trajectory;
  double preroll_s = 5.0;             // hold the first setpoint this long before the trajectory starts
  bool produce_sync = true;
  unsigned period_us = 0;             // SYNC period override (0: 0x1006 of the EDS)
  std::uint8_t sensor_id = 2, valve_id = 3;
  int recover_cycles = 500;           // a fault must be gone this long before control resumes
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

 private:
  void configureFromOd();
  void applyOverrides();
  void onSync(std::uint8_t counter, canopen::TimeUs now) noexcept;
  void raise(Fault f) noexcept;

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
  Fault pending_ = Fault::None;  // raised from hooks, taken in the cycle
  int clear_cycles_ = 0;
  std::uint64_t faults_raised_ = 0;
  std::uint64_t config_errors_ = 0;
  bool traj_override_ = false;
  double last_u_ = -5.0;
  std::atomic<Fault> fault_pub_{Fault::None};
  std::atomic<double> run_time_pub_{0.0};
  canopen::TimeUs last_sync_ = 0;
  CycleStats stats_;
  SpscRing<CycleRecord, 1 << 15> records_;
};

}  // namespace pamc::nodes
