// The Bouc-Wen reference model of the paper, eq. (2) with m = 1, in its discrete form (6).
//
//   h_{k+1} = h_k + [alpha u_d - beta u_d |h_k| - gamma |u_d| h_k + f_h] Ts,  u_d = (u_k - u_{k-1}) / Ts
//   Y_k     = k rho u_k + b + k (1 - rho) h_k
//
// Scale: with m = 1 the h-equation is homogeneous in h apart from the alpha term, so h -> c h with
// (alpha, k(1-rho)) -> (c alpha, k(1-rho)/c) leaves Y unchanged for any c > 0 (beta and gamma keep
// their values; c < 0 also flips the sign of beta). Identification therefore fixes alpha = 1 (h then
// has the unit of u, volts) and lets k(1-rho) take either sign: rho > 1 is the counter-clockwise
// (lagging) loop that the paper expresses with alpha < 0 and rho <= 1.
#pragma once

#include <cmath>

namespace pamc::model {

struct BoucWenParams {
  double k = 5.0;       // stiffness coefficient [mm/V]
  double rho = 0.8;     // weight of the elastic part [-]
  double b = 20.0;      // offset [mm]
  double alpha = 1.0;   // [-]
  double beta = 0.3;    // [1/V]
  double gamma = 0.3;   // [1/V]
};

constexpr int kBoucWenParams = 6;
inline const char* const kBoucWenNames[kBoucWenParams] = {"k", "rho", "b", "alpha", "beta", "gamma"};

// Output of eq. (2)/(6) for input u and hysteresis state h.
inline double boucWenOutput(const BoucWenParams& p, double u, double h) noexcept {
  return p.k * p.rho * u + p.b + p.k * (1.0 - p.rho) * h;
}

// h_{k+1} of eq. (6) for the input increment du = u_k - u_{k-1} and the modelling error f_h.
// Explicit Euler is exact to first order in du; a command jump of several volts in one sample
// (a square-wave setpoint through a PI) would make it overshoot, so large increments are
// split into equal sub-steps of the same formula. For the slow inputs of the paper the loop
// runs once and this is eq. (6) verbatim.
inline double boucWenNext(const BoucWenParams& p, double h, double du, double f_h, double Ts) noexcept {
  const double stiff = (std::fabs(p.beta) + std::fabs(p.gamma)) * std::fabs(du);
  int n = 1;
  if (stiff > 0.25) {
    // Capped before the conversion: a huge beta, gamma or du must not overflow the int.
    const double steps = std::ceil(stiff / 0.25);
    n = steps < 256.0 ? static_cast<int>(steps) : 256;
  }
  const double d = du / n;
  const double ad = std::fabs(d);
  for (int i = 0; i < n; ++i) {
    h += p.alpha * d - p.beta * d * std::fabs(h) - p.gamma * ad * h;
  }
  h += f_h * Ts;
  // Keep a diverging parameter set (beta + gamma < 0) finite so a fitness can reject it;
  // NaN passes through so the caller's health checks see it.
  if (std::fabs(h) > 1e9) h = std::copysign(1e9, h);
  return h;
}

}  // namespace pamc::model
