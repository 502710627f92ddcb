// Whether the control loop runs its model outside the range it was identified on (model.json's
// `range`), or where the model does not move as the muscle does (the MBC's response monitor,
// ControlOutput::model_distrusted): the cycle notes the first such sample, with its numbers, and publishes
// it once; a thread outside the cycle (the fault reporter) says it in one line. Nothing formatted or
// allocated in step().
#pragma once

#include <atomic>
#include <cstdio>
#include <string>

#include "model/operating_range.hpp"

namespace pamc::nodes {

class RangeWatch {
 public:
  // A new run with the model's range (unknown: nothing is watched).
  void configure(const model::OperatingRange& r, double Ts) noexcept {
    seen_.store(false, std::memory_order_release);  // first: no reader takes the new range for the old sample
    distrust_seen_.store(false, std::memory_order_release);
    range_ = r;
    Ts_ = Ts;
    primed_ = false;
  }

  // One cycle: the command sent u [V relative], the measured position y [mm], at run time t [s].
  void step(double t, double u, double y) noexcept {
    if (!range_.known || seen_.load(std::memory_order_relaxed)) return;
    const double rate = primed_ ? (u - u_prev_) / Ts_ : 0.0;
    u_prev_ = u;
    primed_ = true;
    const auto e = range_.check(u, y, rate);
    if (e == model::RangeExcess::None) return;
    first_ = Sample{t, u, y, rate, e};
    seen_.store(true, std::memory_order_release);
  }

  // One cycle's verdict of the MBC's response monitor, at run time t [s].
  void stepResponse(double t, bool distrusted, double ratio) noexcept {
    if (!distrusted || distrust_seen_.load(std::memory_order_relaxed)) return;
    distrust_ = {t, ratio};
    distrust_seen_.store(true, std::memory_order_release);
  }

  // Any thread: whether the model has run outside (the first sample is then fixed).
  bool outside() const noexcept { return seen_.load(std::memory_order_acquire); }
  bool watching() const noexcept { return range_.known; }

  // Any thread: whether the MBC has taken its feedforward off for a model that moves otherwise.
  bool distrusted() const noexcept { return distrust_seen_.load(std::memory_order_acquire); }
  // The one line (call only when distrusted()).
  std::string describeDistrust() const {
    char b[320];
    std::snprintf(b, sizeof b,
                  "note: the model does not move as the muscle does from t = %.3f s: the muscle moved %.3g times what "
                  "the model said over the last second (a feedforward from it helps between 0 and 2); the MBC's "
                  "feedforward is off until that ratio is back within 0.5-1.5",
                  distrust_.t, distrust_.ratio);
    return b;
  }

  // The one line (call only when outside()).
  std::string describe() const {
    const auto& r = range_;
    const char* q = model::rangeQuantity(first_.excess);
    double v = first_.u, lo = r.input.lo, hi = r.input.hi;
    const char* unit = "V";
    if (first_.excess == model::RangeExcess::OutputLow || first_.excess == model::RangeExcess::OutputHigh)
      v = first_.y, lo = r.output.lo, hi = r.output.hi, unit = "mm";
    if (first_.excess == model::RangeExcess::RateLow || first_.excess == model::RangeExcess::RateHigh)
      v = first_.rate, lo = r.rate.lo, hi = r.rate.hi, unit = "V/s";
    char b[400];
    std::snprintf(
        b, sizeof b,
        "note: the model runs outside the range it was identified on from t = %.3f s: %s %.4g %s, identified "
        "on [%.4g, %.4g] %s (its range: input [%.4g, %.4g] V, output [%.4g, %.4g] mm, input rate [%.4g, %.4g] V/s)",
        first_.t, q, v, unit, lo, hi, unit, r.input.lo, r.input.hi, r.output.lo, r.output.hi, r.rate.lo, r.rate.hi);
    return b;
  }

 private:
  struct Sample {
    double t = 0.0, u = 0.0, y = 0.0, rate = 0.0;
    model::RangeExcess excess = model::RangeExcess::None;
  };
  model::OperatingRange range_{};
  double Ts_ = 1e-3;
  double u_prev_ = 0.0;
  bool primed_ = false;
  Sample first_{};
  std::atomic<bool> seen_{false};
  struct Distrust {
    double t = 0.0, ratio = 0.0;
  } distrust_{};
  std::atomic<bool> distrust_seen_{false};
};

}  // namespace pamc::nodes
