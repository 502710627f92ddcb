// The Bouc-Wen reference model of the paper, eq. (2) with m = 1, in its discrete form (6).
//
//   h_{k+1} = h_k + [alpha u_d - beta u_d |h_k| - gamma |u_d| h_k + f_h] Ts,  u_d = (u_k - u_{k-1}) / Ts
//   Y_k     = k rho u_k + b + k (1 - rho) h_k
//
// boucWenNext integrates the h-equation of (2) exactly over each input increment (the same as (6) to
// first order in u_d Ts, and the continuous model's h for any increment); f_h enters as f_h Ts.
//
// Scale: with m = 1 the h-equation is homogeneous in h apart from the alpha term, so h -> c h with
// (alpha, k(1-rho)) -> (c alpha, k(1-rho)/c) leaves Y unchanged for any c > 0 (beta and gamma keep
// their values; c < 0 also flips the sign of beta). Identification therefore fixes alpha = 1 (h then
// has the unit of u, volts) and lets k(1-rho) take either sign: rho > 1 is the counter-clockwise
// (lagging) loop that the paper expresses with alpha < 0 and rho <= 1.
#pragma once

#include <algorithm>
#include <cmath>
#include <string>

namespace pamc::model {

struct BoucWenParams {
  double k = 5.0;      // stiffness coefficient [mm/V]
  double rho = 0.8;    // weight of the elastic part [-]
  double b = 20.0;     // offset [mm]
  double alpha = 1.0;  // [-]
  double beta = 0.3;   // [1/V]
  double gamma = 0.3;  // [1/V]
};

constexpr int kBoucWenParams = 6;
inline const char* const kBoucWenNames[kBoucWenParams] = {"k", "rho", "b", "alpha", "beta", "gamma"};

// Output of eq. (2)/(6) for input u and hysteresis state h.
inline double boucWenOutput(const BoucWenParams& p, double u, double h) noexcept {
  return p.k * p.rho * u + p.b + p.k * (1.0 - p.rho) * h;
}

namespace detail {
// (1 - exp(-y)) / y for |y| < kSeriesLimit: its series to y^8, within 2e-12 relative. Evaluated in
// pairs of terms (Estrin's scheme) rather than by Horner's rule: a fit simulates a record sample by
// sample, and Horner's chain of eight dependent multiply-adds was the longest latency of the step.
constexpr double kSeriesLimit = 0.25;
inline double boucWenSeries(double y) noexcept {
  constexpr double k2 = 1.0 / 2, k3 = 1.0 / 6, k4 = 1.0 / 24, k5 = 1.0 / 120, k6 = 1.0 / 720, k7 = 1.0 / 5040,
                   k8 = 1.0 / 40320, k9 = 1.0 / 362880;
  const double y2 = y * y, y4 = y2 * y2;
  const double p0 = 1.0 - k2 * y, p1 = k3 - k4 * y, p2 = k5 - k6 * y, p3 = k7 - k8 * y;
  return (p0 + y2 * p1) + y4 * ((p2 + y2 * p3) + y4 * k9);
}

// (1 - exp(-c v)) / c, the factor of the exact step below (v for c = 0). Below |c v| = kSeriesLimit
// the series, which costs no exp (a record sampled at 100 Hz moves by more than 1e-2 V per sample, and
// expm1 was then a sixth of a fit's time).
inline double boucWenTravel(double c, double v) noexcept {
  const double y = c * v;
  return std::fabs(y) < kSeriesLimit ? v * boucWenSeries(y) : -std::expm1(-y) / c;
}

// Side of h = 0 whose equation applies; at h = 0 the side that the flow (a) enters.
inline double boucWenSide(double h, double a) noexcept { return h > 0.0 ? 1.0 : h < 0.0 ? -1.0 : a > 0.0 ? 1.0 : -1.0; }

// The rest of an increment that crossed h = 0: at the input travel v0 = log(1 + x) / c, x = -c h / a
// (> -1 here; -h / a for c = 0); the rest follows the other side's equation from h = 0. Out of line:
// it runs once per crossing, and inlined at every step it only makes the step's code longer.
[[gnu::noinline]] inline double boucWenCrossed(const BoucWenParams& p, double h, double s, double v, double a,
                                               double side, double c) noexcept {
  const double x = -c * h / a;
  const double v0 = x == 0.0 ? -h / a : std::log1p(x) / c;
  const double c2 = p.gamma - s * side * p.beta;
  return a * boucWenTravel(c2, std::max(v - v0, 0.0));
}

// The exact step from h over the input travel v in direction s (a = s alpha) on the given side, whose
// c and travel factor boucWenTravel(c, v) the caller has computed.
inline double boucWenAdvance(const BoucWenParams& p, double h, double s, double v, double a, double side, double c,
                             double travel) noexcept {
  const double rate = a - c * h;  // dh/dv at the start
  if (rate == 0.0) return h;      // at a fixed point h stays (also keeps 0 * inf from a diverging c away)
  const double h1 = h + rate * travel;
  if (!(side * h1 < 0.0)) return h1;
  return boucWenCrossed(p, h, s, v, a, side, c);
}

// Bound of h: a diverging parameter set (beta + gamma < 0) is kept finite so a fitness can reject it.
constexpr double kHLimit = 1e9;

// f_h Ts added, h clamped to +-kHLimit, NaN passed through so the caller's health checks see it.
inline double boucWenFinish(double h, double f_h, double Ts) noexcept {
  h += f_h * Ts;
  if (std::fabs(h) > kHLimit) h = std::copysign(kHLimit, h);
  return h;
}
}  // namespace detail

// h_{k+1} for the input increment du = u_k - u_{k-1} and the modelling error f_h: eq. (6), but with
// the h-equation integrated exactly over the increment instead of by one explicit Euler step.
// Euler's error grows with |du| (beta + gamma): a command jump of several volts in one sample (a
// square-wave setpoint through a PI) made it overshoot, and equal Euler sub-steps still left the
// discrete model millimetres off the continuous one at the jumps. For m = 1 and a monotone increment
// the equation is a linear ODE in the input travelled v = |du| on each side of h = 0,
//   dh/dv = a - c h,  a = s alpha,  c = gamma + s sign(h) beta,  s = sign(du),
// whose solution is h(v) = h0 + (a - c h0) (1 - exp(-c v)) / c. h moves monotonically (a 1-D
// autonomous ODE), so it crosses 0 at most once; the solution of the starting side then ends on the
// other side, and only then is the step redone in two parts. For the slow inputs of the paper c v is
// small and a short series replaces exp, so they cost about what Euler did; the result differs from
// Euler's eq. (6) by O((c v)^2) per sample.
// A simulation's h runs from sample to sample through here: where both sides' travel factors are
// series, both are computed from du alone, off that chain, which is then the side test and one
// multiply-add (the same numbers as computing the side's only).
inline double boucWenNext(const BoucWenParams& p, double h, double du, double f_h, double Ts) noexcept {
  if (du != 0.0) {  // also for a NaN du, which then reaches h
    const double s = du > 0.0 ? 1.0 : -1.0;
    const double v = std::fabs(du);
    const double a = s * p.alpha;
    const double c_pos = p.gamma + s * p.beta, c_neg = p.gamma - s * p.beta;  // c on the side h > 0, h < 0
    const double y_pos = c_pos * v, y_neg = c_neg * v;
    const double side = detail::boucWenSide(h, a);
    const bool pos = side > 0.0;
    if ((std::fabs(y_pos) < detail::kSeriesLimit) & (std::fabs(y_neg) < detail::kSeriesLimit)) {
      const double t_pos = v * detail::boucWenSeries(y_pos), t_neg = v * detail::boucWenSeries(y_neg);
      h = detail::boucWenAdvance(p, h, s, v, a, side, pos ? c_pos : c_neg, pos ? t_pos : t_neg);
    } else {
      const double c = pos ? c_pos : c_neg;
      h = detail::boucWenAdvance(p, h, s, v, a, side, c, detail::boucWenTravel(c, v));
    }
  }
  return detail::boucWenFinish(h, f_h, Ts);
}

// boucWenNext for one increment du applied to several states (the estimator's sigma points), to the
// bit: c and the travel factor depend on du and the side of h = 0 alone, so they are computed once for
// the side of a typical state h_hint (the sigma points' mean: they lie on its side but near h = 0), and
// a state costs a few multiplications; a state on the other side computes its own.
class BoucWenStep {
 public:
  BoucWenStep(const BoucWenParams& p, double du, double h_hint = 0.0) noexcept : p_(&p), moving_(du != 0.0) {
    if (!moving_) return;
    s_ = du > 0.0 ? 1.0 : -1.0;
    v_ = std::fabs(du);
    a_ = s_ * p.alpha;
    side_ = detail::boucWenSide(h_hint, a_);
    c_[0] = p.gamma - s_ * p.beta;
    c_[1] = p.gamma + s_ * p.beta;
    travel_ = detail::boucWenTravel(c_[side_ > 0.0 ? 1 : 0], v_);
  }
  double operator()(double h, double f_h, double Ts) const noexcept {
    return detail::boucWenFinish(advance(h), f_h, Ts);
  }
  // The hysteresis over the increment, f_h not yet added.
  double advance(double h) const noexcept {
    if (!moving_) return h;
    const double side = detail::boucWenSide(h, a_);
    const double c = c_[side > 0.0 ? 1 : 0];
    const double travel = side == side_ ? travel_ : otherTravel(c);
    return detail::boucWenAdvance(*p_, h, s_, v_, a_, side, c, travel);
  }

 private:
  [[gnu::noinline]] double otherTravel(double c) const noexcept { return detail::boucWenTravel(c, v_); }
  const BoucWenParams* p_;
  bool moving_;
  double s_ = 0.0, v_ = 0.0, a_ = 0.0, side_ = 0.0;
  double c_[2] = {0.0, 0.0};  // side -1, +1
  double travel_ = 0.0;       // of side_
};

// The continuous model's condition for h to stay bounded for every input from h = 0. On each side of
// h = 0 the h-equation is dh/dv = a - c h over the input travel v (see boucWenNext). With h' = h / alpha
// (alpha' = 1, beta' = beta sign(alpha), gamma' = gamma): loading away from 0 ends at |h'| = 1 / (beta' +
// gamma'), which needs beta' + gamma' > 0; a reversal from there runs with c = gamma' - beta' and turns
// back towards 0 only if 1 - (beta' - gamma') / (beta' + gamma') >= 0, i.e. gamma' >= 0. With gamma < 0 a
// sine's first reversal from the loop's end diverges (tests/unit/test_model.cpp).
inline bool boucWenBounded(const BoucWenParams& p) noexcept {
  return p.alpha == 0.0 || (std::copysign(1.0, p.alpha) * p.beta + p.gamma > 0.0 && p.gamma >= 0.0);
}

// Whether a parameter set is bounded (see bouc_wen.cpp): the sign condition of the continuous model,
// then the discrete form driven through sweeps and full-range steps of the command range
// [u_min, u_max]. On false, why says which test failed. Slow (a few thousand steps): call it when a
// parameter set is checked, never in a cycle.
bool boucWenStable(const BoucWenParams& p, double u_min, double u_max, std::string* why = nullptr);

}  // namespace pamc::model
