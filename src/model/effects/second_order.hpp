// The one-sample map of a mass on a spring and damper driven by an input, shared by mass_spring and
// force_loop: y'' = wn^2 (in - y) - 2 zeta wn y', the input held over the sample. Exact: the matrix
// exponential of the system with its input, [[A, B], [0, 1]] = exp(Ts [[F, G], [0, 0]]),
// F = [[0, 1], [-wn^2, -2 zeta wn]], G = [0, wn^2], by scaling and squaring of its Taylor series. The
// map used to be semi-implicit Euler with sub-steps of wn h <= 0.05 - one step per sample at 8 Hz,
// whose few percent of phase error an independent continuous-time simulation showed at once (a ringing
// payload at 8 Hz fitted as force_loop at 15x the noise, tests/oracle).
#pragma once

#include <algorithm>
#include <cmath>

#include "model/small_expm.hpp"

namespace pamc::model {

// Writes A (row-major: a11, a12, a21, a22) and B (b1, b2) as out[0..5].
inline void secondOrderMap(double fn, double zeta, double Ts, double* out) noexcept {
  const double wn = 2.0 * M_PI * std::max(fn, 1e-6);
  zeta = std::max(zeta, 0.0);
  const SmallMat<3> m{0.0, Ts, 0.0, -wn * wn * Ts, -2.0 * zeta * wn * Ts, wn * wn * Ts, 0.0, 0.0, 0.0};
  // Largest entry at most 1/6 (row norm 1/2): 16 terms are below 1e-17 relative.
  const SmallMat<3> e = smallExpm<3>(m, 0.5 / 3.0, 16);
  out[0] = e[0];
  out[1] = e[1];
  out[2] = e[3];
  out[3] = e[4];
  out[4] = e[2];
  out[5] = e[5];
}

}  // namespace pamc::model
