// Where a model holds: the range of input, output and input rate of the record it was identified on.
// A model used outside it predicts from what it never saw (docs/MODELING.md, "Designing a record");
// `pamc compare` reports the share of samples outside, and a controller given the model says when it
// runs there. check() is noexcept and allocation-free, for the control cycle.
#pragma once

#include <algorithm>
#include <cstddef>
#include <limits>

namespace pamc::model {

// Which quantity left the range first (None: inside, or the range is not known).
enum class RangeExcess { None, InputLow, InputHigh, OutputLow, OutputHigh, RateLow, RateHigh };

struct Interval {
  double lo = 0.0, hi = 0.0;
  bool contains(double v) const noexcept { return v >= lo && v <= hi; }
};

struct OperatingRange {
  bool known = false;  // false for a model file written before ranges were recorded
  Interval input;      // command u [file units, V]
  Interval output;     // measured y [file units, mm]
  Interval rate;       // du/dt [input units per second]

  // The range of a record of n samples at step Ts (rates from consecutive samples).
  static OperatingRange of(const double* u, const double* y, std::size_t n, double Ts) noexcept {
    OperatingRange r;
    if (n == 0 || !(Ts > 0.0)) return r;
    constexpr double inf = std::numeric_limits<double>::infinity();
    r.input = {inf, -inf};
    r.output = {inf, -inf};
    r.rate = {0.0, 0.0};
    for (std::size_t i = 0; i < n; ++i) {
      widen(r.input, u[i]);
      widen(r.output, y[i]);
      if (i > 0) widen(r.rate, (u[i] - u[i - 1]) / Ts);
    }
    r.known = true;
    return r;
  }

  // What of (u, y, du/dt) lies outside, in the order input, output, rate.
  RangeExcess check(double u, double y, double du_dt) const noexcept {
    if (!known) return RangeExcess::None;
    if (u < input.lo) return RangeExcess::InputLow;
    if (u > input.hi) return RangeExcess::InputHigh;
    if (y < output.lo) return RangeExcess::OutputLow;
    if (y > output.hi) return RangeExcess::OutputHigh;
    if (du_dt < rate.lo) return RangeExcess::RateLow;
    if (du_dt > rate.hi) return RangeExcess::RateHigh;
    return RangeExcess::None;
  }

 private:
  static void widen(Interval& i, double v) noexcept {
    i.lo = std::min(i.lo, v);
    i.hi = std::max(i.hi, v);
  }
};

// "input", "output" or "input rate" for an excess (empty for None).
inline const char* rangeQuantity(RangeExcess e) noexcept {
  switch (e) {
    case RangeExcess::InputLow:
    case RangeExcess::InputHigh: return "input";
    case RangeExcess::OutputLow:
    case RangeExcess::OutputHigh: return "output";
    case RangeExcess::RateLow:
    case RangeExcess::RateHigh: return "input rate";
    case RangeExcess::None: break;
  }
  return "";
}

}  // namespace pamc::model
