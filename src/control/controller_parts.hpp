// The parts the controllers are built from (controller.cpp, mbc.cpp): the commands in flight, the PI of
// eq. (16) with its anti-windup, the last usable position, the MBC's setpoint governor and its delay line.
// noexcept and allocation-free.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

#include "control/controller.hpp"

namespace pamc::control::detail {

// The last N values pushed (N a power of two), to read one from up to N - 1 pushes ago.
template <unsigned N>
class History {
  static_assert(N >= 2 && (N & (N - 1)) == 0, "N must be a power of two");

 public:
  void fill(double v) noexcept { buf_.fill(v); }
  void push(double v) noexcept {
    head_ = (head_ + 1) & (N - 1);
    buf_[head_] = v;
  }
  // ago = 0: the latest value.
  double get(int ago) const noexcept { return buf_[(head_ - static_cast<unsigned>(ago)) & (N - 1)]; }
  void replaceLatest(double v) noexcept { buf_[head_] = v; }

 private:
  std::array<double, N> buf_{};
  unsigned head_ = 0;
};

// The commands of the last few cycles, to tell the estimators which one was in effect when a
// measurement was taken.
using CommandHistory = History<8>;
// The MBC's governed setpoint of the last cycles: beyond the longest horizon, 2000 samples.
using DelayLine = History<2048>;

// A setpoint follower limited in rate and acceleration (a reference governor): each step moves towards the
// target at the setpoint's own slope plus the speed from which it can still brake to it, within
// +-rate_mm_s, the speed changing by at most accel_mm_s2 Ts per step. A ramp no steeper than ramp_mm_s
// (the rate unless given) passes (after a start of slope / accel) without lag - one steeper than the rate
// within its slope plus the rate; a jump, which is no slope, is taken at the rate and arrived at without
// overshoot.
// rate 0: the target passes as it is.
class SetpointGovernor {
 public:
  void configure(double rate_mm_s, double accel_mm_s2, double Ts, double ramp_mm_s = 0.0) noexcept {
    rate_ = rate_mm_s, accel_ = accel_mm_s2, Ts_ = Ts, ramp_ = std::max(ramp_mm_s, rate_mm_s);
  }
  // The acceleration of what follows: a higher one at once (braking only gets easier), a lower one once the
  // follower is nearly at rest (mid-move it could no longer brake onto the target at the lower one).
  void setAccel(double accel_mm_s2) noexcept {
    if (accel_mm_s2 >= accel_ || std::fabs(v_) <= accel_mm_s2 * Ts_) accel_ = accel_mm_s2;
  }
  double accel() const noexcept { return accel_; }
  // At y at rest; a non-finite y starts it at the first target.
  void reset(double y) noexcept {
    r_ = prev_ = y;
    v_ = 0.0;
  }
  double step(double target) noexcept {
    if (!std::isfinite(target)) return r_;
    if (!(rate_ > 0.0) || !std::isfinite(r_)) return r_ = prev_ = target;
    double slope = (target - prev_) / Ts_;
    prev_ = target;
    if (!(std::fabs(slope) <= ramp_)) slope = 0.0;  // a jump
    const double d = target - r_;
    // The speed from which braking at accel, a step of accel Ts at a time, stops on the target:
    // v^2 / (2 accel) + v Ts / 2 = |d|.
    const double half = 0.5 * accel_ * Ts_;
    const double brake = std::copysign(std::sqrt(half * half + 2.0 * accel_ * std::fabs(d)) - half, d);
    // A ramp steeper than the rate (a governor lowered to a slow model's pace) passes, caught up with at the rate.
    const double cap = std::fabs(slope) > rate_ ? std::fabs(slope) + rate_ : rate_;
    const double v_want = std::clamp(slope + brake, -cap, cap);
    const double dv = accel_ * Ts_;
    v_ += std::clamp(v_want - v_, -dv, dv);
    r_ += v_ * Ts_;
    return r_;
  }

 private:
  double rate_ = 0.0, accel_ = 1.0, Ts_ = 1e-3, ramp_ = 0.0;
  double r_ = 0.0, v_ = 0.0, prev_ = 0.0;
};

// PI of eq. (16) with conditional integration as anti-windup.
class PiCore {
 public:
  // beside_feedforward: the integral is a correction to a feedforward that carries the command, so it
  // may span the command's difference, [u_min - u_max, u_max - u_min]; alone it is the command's own
  // level, within [u_min, u_max].
  void configure(const ControllerConfig& c, bool beside_feedforward = false) {
    kp_ = c.kp;
    ki_ts_ = c.ki * c.Ts;  // continuous-time Ki [V/(mm s)], integral as sum of e*Ts
    u_min_ = c.u_min;
    u_max_ = c.u_max;
    i_lo_ = beside_feedforward ? c.u_min - c.u_max : c.u_min;
    i_hi_ = beside_feedforward ? c.u_max - c.u_min : c.u_max;
  }
  void reset(double integral) noexcept {
    integ_ = std::isfinite(integral) ? std::clamp(integral, i_lo_, i_hi_) : 0.5 * (u_min_ + u_max_);
  }
  // Nominal output with this cycle's error integrated (tentatively). integrate = false holds the
  // integral (no usable measurement); a non-finite error counts as none and is not integrated.
  double nominal(double e, bool integrate = true) noexcept {
    if (!std::isfinite(e)) e = 0.0, integrate = false;
    e_ = e;
    pending_ = integrate ? std::clamp(integ_ + scale_ * ki_ts_ * e, i_lo_, i_hi_) : integ_;
    return scale_ * kp_ * e + pending_;
  }
  // Both gains times s (1: as configured) from the next nominal() on; the integral stays where it is.
  void scale(double s) noexcept { scale_ = std::isfinite(s) ? std::clamp(s, 0.0, 1.0) : 1.0; }
  // Saturates u_n + extra; keeps the integration only if it does not push further into the limit.
  double finish(double u_n, double extra, bool& saturated, double& u_n_out) noexcept {
    if (!std::isfinite(extra)) extra = 0.0;
    const double raw = u_n + extra;
    const double u = std::clamp(raw, u_min_, u_max_);
    saturated = u != raw;
    before_ = integ_;
    if (saturated && (raw - u) * e_ > 0.0) {
      u_n_out = u_n - pending_ + integ_;  // integration undone
      return out_ = std::clamp(u_n_out + extra, u_min_, u_max_);
    }
    integ_ = pending_;
    u_n_out = u_n;
    return out_ = u;
  }
  // The command that went out was u_applied, not finish()'s: this cycle's integration is undone where
  // it pushed further past it.
  void limited(double u_applied) noexcept {
    if (std::isfinite(u_applied) && (out_ - u_applied) * e_ > 0.0) integ_ = before_;
    out_ = u_applied;
  }
  double integral() const noexcept { return integ_; }
  // Moves the integral by delta (a feedforward switched on or off beside it, bumpless).
  void shift(double delta) noexcept {
    if (std::isfinite(delta)) integ_ = std::clamp(integ_ + delta, i_lo_, i_hi_);
  }

 private:
  double kp_ = 0, ki_ts_ = 0, u_min_ = kCommandMin, u_max_ = kCommandMax;
  double scale_ = 1.0;                              // the gains' share in effect (scale)
  double i_lo_ = kCommandMin, i_hi_ = kCommandMax;  // the integral's limits (configure)
  double integ_ = 0, pending_ = 0, e_ = 0;
  double before_ = 0, out_ = 0;  // the integral before this cycle's, the command finish() gave
};

// A controller whose command is the PI's plus a compensation, with the commands in flight (PI+AMC, PID+ESO,
// MBC): the command that went out replaces the latest sent, and the PI's integration of the cycle is undone
// where it pushed further past it.
class PiBased : public Controller {
 public:
  void limited(double u_applied) noexcept override {
    pi_.limited(u_applied);
    hist_.replaceLatest(u_applied);
  }
  double integral() const noexcept override { return pi_.integral(); }

 protected:
  PiCore pi_;
  CommandHistory hist_;
};

// Whether a model moves as the muscle does (the MBC's feedforward, docs/CONTROL.md "A model that moves
// otherwise than the muscle"). Each cycle takes the model's output driven by the commands in effect and the
// measured position; their changes over `span` cycles are regressed, the muscle's on the model's, with
// exponential forgetting of time constant tau: ratio = sum(dp dm) / sum(dm dm). A feedforward from the
// model's inverse moves the muscle by ratio times what the model was asked for, so it leaves a part
// |ratio - 1| of the setpoint's motion to the PI: it helps while that part is below 1, the whole motion the
// PI faces alone. The model is distrusted where the part exceeds that break-even (kOff) and trusted again
// below kOn (chosen; a first choice of 0.5 and 0.25 took the feedforward from models it helped); judged
// from two windows after a start (the first is dropped) and while the model moves at least kMinSpeed rms.
class ResponseMonitor {
 public:
  static constexpr double kOff = 1.0, kOn = 0.5;
  static constexpr double kMinSpeed = 0.5;  // [output units / s] rms over the window (chosen)
  void configure(double Ts, double tau_s, double span_s) noexcept {
    span_ = std::clamp(static_cast<int>(std::lround(span_s / Ts)), 1, 1023);
    a_ = std::min(1.0, Ts / tau_s);
    warm_ = static_cast<long>(std::ceil(tau_s / Ts));
    min_mm_ = kMinSpeed * kMinSpeed * span_ * Ts * span_ * Ts;
  }
  void reset() noexcept {
    forget();
    ratio_ = 1.0;
    trusted_ = true;
  }
  // A cycle not to judge (the model outside the range it was identified on): the window starts again
  // after it, the verdict stays. Cheap: it runs in every such cycle.
  void forget() noexcept {
    pushed_ = seen_ = 0;
    smm_ = smp_ = 0.0;
  }
  // One cycle. A non-finite value is not judged.
  void step(double model_y, double y) noexcept {
    model_.push(model_y), meas_.push(y);
    if (++pushed_ <= span_) return;  // a change over span_ cycles needs span_ + 1 values since forget()
    const double dm = model_y - model_.get(span_), dp = y - meas_.get(span_);
    if (!std::isfinite(dm) || !std::isfinite(dp)) return;
    // The first window after a start is the start's: the model's state there is a guess (at rest at the
    // command it started from), and a vented muscle fills in it. It is dropped.
    if (++seen_ == warm_) smm_ = smp_ = 0.0;
    smm_ += (dm * dm - smm_) * a_;
    smp_ += (dp * dm - smp_) * a_;
    if (seen_ < 2 * warm_ || smm_ < min_mm_) return;
    ratio_ = smp_ / smm_;
    const double part = std::fabs(ratio_ - 1.0);
    if (trusted_ && part > kOff) trusted_ = false;
    if (!trusted_ && part < kOn) trusted_ = true;
  }
  bool trusted() const noexcept { return trusted_; }
  double ratio() const noexcept { return ratio_; }  // the last judged ratio (1 before any)

 private:
  History<1024> model_, meas_;
  int span_ = 20;
  double a_ = 1e-3, min_mm_ = 0.0;
  long warm_ = 1, seen_ = 0;  // a window's worth of cycles; the cycles judged since the start
  long pushed_ = 0;           // values pushed since forget()
  double smm_ = 0.0, smp_ = 0.0, ratio_ = 1.0;
  bool trusted_ = true;
};

// The last usable (finite) measured position: a non-finite one is never used.
class LastGood {
 public:
  void reset(double y0) noexcept { y_ = std::isfinite(y0) ? y0 : NAN; }
  // True if y is usable (and now the last good one).
  bool take(double y) noexcept {
    if (!std::isfinite(y)) return false;
    y_ = y;
    return true;
  }
  double get() const noexcept { return y_; }  // NaN until a finite position was seen

 private:
  double y_ = NAN;
};

}  // namespace pamc::control::detail
