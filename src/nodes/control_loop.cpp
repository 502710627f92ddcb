#include "nodes/control_loop.hpp"

#include <algorithm>
#include <cmath>

namespace pamc::nodes {

void ControlLoop::configure(std::unique_ptr<control::Controller> c, control::Kind kind, const control::Trajectory& traj,
                            double Ts, double preroll_s, double safe_u) {
  Ts_ = Ts;
  kind_ = kind;
  traj_ = traj;
  ctrl_ = std::move(c);
  active_ = false;
  run_started_ = false;
  ramp_ = false;
  cycle_ = 0;
  preroll_cycles_ = static_cast<std::uint64_t>(std::llround(preroll_s / Ts_));
  last_u_ = safe_u;
  publishTime(0.0);
}

void ControlLoop::stop() noexcept {
  active_ = run_started_ = false;
  ramp_ = slew_ = false;
}

void ControlLoop::activateOn(const PositionSample& s) noexcept {
  if (active_ || !s.usable) return;
  ctrl_->activate(last_u_, s.y);
  active_ = true;
}

void ControlLoop::count() noexcept {
  if (!active_) return;
  ++cycle_;
  run_started_ = cycle_ > preroll_cycles_;
}

ControlLoop::Setpoint ControlLoop::setpointNow() noexcept {
  const double t = runSeconds();
  if (ramp_ && cycle_ >= ramp_k0_ + ramp_cycles_) ramp_ = false;
  return Setpoint{t, setpoint(t, 0)};
}

CycleRecord ControlLoop::record(const PositionSample& s, Setpoint sp, double u) const noexcept {
  return CycleRecord{static_cast<std::uint32_t>(cycle_), sp.t, sp.yd, s.y, u, 0.0, 0.0, s.y, 0, 0.0f};
}

CycleRecord ControlLoop::holdSafe(const PositionSample& s, Setpoint sp, double safe_u) noexcept {
  last_u_ = safe_u;
  return record(s, sp, safe_u);
}

CycleRecord ControlLoop::idle(const PositionSample& s, Setpoint sp, double safe_u) const noexcept {
  return record(s, sp, safe_u);
}

bool ControlLoop::step(const PositionSample& s, Setpoint sp, double safe_u, CycleRecord& rec) noexcept {
  const int la = ctrl_->lookahead();
  const double yd_ahead = run_started_ ? setpoint(sp.t + la * Ts_, la) : setpoint(0.0, la);
  const auto o = ctrl_->update(sp.yd, yd_ahead, s.y_ctrl);
  rec = CycleRecord{static_cast<std::uint32_t>(cycle_), sp.t, sp.yd, s.y, o.u, o.u_n, o.u_c, o.y_hat, 0, 0.0f};
  if (!std::isfinite(o.u) || o.estimator_reset) {
    last_u_ = safe_u;
    return false;
  }
  if (slew_) {
    // Bumpless transfer: a restarted estimator may ask for a step (the AMC's model prediction from
    // rest); the valve gets it as a ramp, until the controller's command is within reach.
    const double u = std::clamp(o.u, last_u_ - ramp_slew_v_, last_u_ + ramp_slew_v_);
    if (!ramp_ && u == o.u) slew_ = false;
    if (u != o.u) ctrl_->limited(u);  // what went out, for its estimator and its integral
    last_u_ = u;
  } else {
    last_u_ = o.u;
  }
  range_watch_.step(sp.t, last_u_, s.y);
  range_watch_.stepResponse(sp.t, o.model_distrusted, o.model_ratio);
  return true;
}

void ControlLoop::enterSafe(double safe_u) noexcept {
  ramp_ = slew_ = false;
  last_u_ = safe_u;
}

void ControlLoop::restartFrom(double y) noexcept {
  ctrl_->activate(last_u_, y);
  startRamp(y);
}

void ControlLoop::recoverFrom(double y, double safe_u) noexcept {
  // Estimator and integrator restart from the safe value; the setpoint starts at the position.
  last_u_ = safe_u;
  restartFrom(y);
}

double ControlLoop::runSeconds() const noexcept {
  return run_started_ ? static_cast<double>(cycle_ - preroll_cycles_) * Ts_ : 0.0;
}

void ControlLoop::startRamp(double y) noexcept {
  // The ramp starts where the setpoint's quantity is now: the position, or - an input passed through to
  // the valve - the command in effect.
  const double from = kind_ == control::Kind::Input ? last_u_ : y;
  const double gap = std::fabs(traj_.at(runSeconds()) - from);
  const double seconds = std::clamp(gap / std::max(ramp_mm_per_s_, 1e-6), 0.05, 5.0);
  ramp_ = true;
  slew_ = true;
  ramp_from_ = from;
  ramp_k0_ = cycle_;
  ramp_cycles_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(seconds / Ts_)));
}

double ControlLoop::setpoint(double t, int ahead) const noexcept {
  const double target = traj_.at(t);
  if (!ramp_) return target;
  const double s =
      static_cast<double>(cycle_ + static_cast<std::uint64_t>(ahead) - ramp_k0_) / static_cast<double>(ramp_cycles_);
  return s >= 1.0 ? target : ramp_from_ + (target - ramp_from_) * s;
}

}  // namespace pamc::nodes
