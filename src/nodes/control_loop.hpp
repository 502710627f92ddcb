// The control loop of the controller node, free of CANopen: each cycle it takes the position latched
// at the SYNC, runs the controller towards the trajectory's setpoint and holds the command the valve
// gets; after a restart (recovery, a committed parameter set) the setpoint ramps from the measured
// position back to the trajectory and the command is rate-limited (bumpless). With Kind::Input the
// trajectory is the valve command itself (an identification input): it ramps from the command in effect. Runs in the
// cycle: nothing allocated, nothing thrown (configure() excepted, which runs between cycles).
#pragma once

#include <atomic>
#include <cstdint>
#include <memory>

#include "nodes/process_data.hpp"
#include "control/controller.hpp"
#include "control/trajectory.hpp"
#include "nodes/cycle_stats.hpp"
#include "nodes/range_watch.hpp"
#include "nodes/position_sample.hpp"

namespace pamc::nodes {

class ControlLoop {
 public:
  ControlLoop(double ramp_mm_per_s, double ramp_slew_v) : ramp_mm_per_s_(ramp_mm_per_s), ramp_slew_v_(ramp_slew_v) {}

  // A new controller and trajectory; the loop starts again at the next usable position.
  void configure(std::unique_ptr<control::Controller> c, control::Kind kind, const control::Trajectory& traj, double Ts,
                 double preroll_s, double safe_u);
  void stop() noexcept;  // the node left Operational
  // Watch whether the commands and positions stay where the controller's model was identified (an
  // unknown range, or a controller that runs no model: nothing is watched).
  void watchRange(const model::OperatingRange& r) noexcept { range_watch_.configure(r, Ts_); }
  const RangeWatch& rangeWatch() const noexcept { return range_watch_; }

  // The cycle, in order: activation on the first usable position, the cycle count, then one of
  // holdSafe / idle / step.
  void activateOn(const PositionSample& s) noexcept;
  void count() noexcept;
  struct Setpoint {
    double t = 0.0, yd = 0.0;
  };
  Setpoint setpointNow() noexcept;  // ends a ramp that has run its course
  CycleRecord holdSafe(const PositionSample& s, Setpoint sp, double safe_u) noexcept;    // safe state
  CycleRecord idle(const PositionSample& s, Setpoint sp, double safe_u) const noexcept;  // not yet active
  // The controller's command (slew-limited after a restart); false when the estimator failed (a
  // non-finite command or a reset): the command is then the safe value.
  bool step(const PositionSample& s, Setpoint sp, double safe_u, CycleRecord& rec) noexcept;

  // Restarts: into the safe state; from the command in effect (a committed set); from the safe value
  // (recovery). The last two ramp from y.
  void enterSafe(double safe_u) noexcept;
  void restartFrom(double y) noexcept;
  void recoverFrom(double y, double safe_u) noexcept;

  std::unique_ptr<control::Controller>& controller() noexcept { return ctrl_; }
  control::Kind kind() const noexcept { return kind_; }
  double period() const noexcept { return Ts_; }
  double command() const noexcept { return last_u_; }  // relative volts
  bool active() const noexcept { return active_; }
  bool running() const noexcept { return run_started_; }
  std::uint64_t cycle() const noexcept { return cycle_; }
  void publishTime(double t) noexcept { run_time_pub_.store(t, std::memory_order_relaxed); }
  double runTime() const noexcept { return run_time_pub_.load(std::memory_order_relaxed); }  // any thread

 private:
  double runSeconds() const noexcept;
  void startRamp(double y) noexcept;
  double setpoint(double t, int ahead) const noexcept;
  CycleRecord record(const PositionSample& s, Setpoint sp, double u) const noexcept;

  std::unique_ptr<control::Controller> ctrl_;
  control::Kind kind_ = control::Kind::PI;
  control::Trajectory traj_;
  double Ts_ = 1e-3;
  bool active_ = false;       // controller activated (usable position seen)
  bool run_started_ = false;  // past the pre-roll
  std::uint64_t cycle_ = 0;   // cycles since activation
  std::uint64_t preroll_cycles_ = 0;
  double last_u_ = pd::kCommandMin;  // the command in effect [V relative]
  // Bumpless return: the setpoint goes from ramp_from_ to the trajectory over ramp_cycles_.
  bool ramp_ = false;
  bool slew_ = false;  // command rate-limited: during the ramp and until the limit no longer binds
  double ramp_from_ = 0.0;
  std::uint64_t ramp_k0_ = 0, ramp_cycles_ = 1;
  double ramp_mm_per_s_, ramp_slew_v_;
  std::atomic<double> run_time_pub_{0.0};
  RangeWatch range_watch_;
};

}  // namespace pamc::nodes
