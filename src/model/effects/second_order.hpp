// The one-sample map of a mass on a spring and damper driven by an input, shared by mass_spring and
// force_loop: y'' = wn^2 (in - y) - 2 zeta wn y', the input held over the sample. Exact: the matrix
// exponential of the system with its input, [[A, B], [0, 1]] = exp(Ts [[F, G], [0, 0]]),
// F = [[0, 1], [-wn^2, -2 zeta wn]], G = [0, wn^2], by scaling and squaring of its Taylor series. The
// map used to be semi-implicit Euler with sub-steps of wn h <= 0.05 - one step per sample at 8 Hz,
// whose few percent of phase error an independent continuous-time simulation showed at once (a ringing
// payload at 8 Hz fitted as force_loop at 15x the noise, tests/oracle).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace pamc::model {

namespace detail {
using Mat3 = std::array<double, 9>;  // row-major
inline Mat3 mul3(const Mat3& a, const Mat3& b) noexcept {
  Mat3 c{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      for (int k = 0; k < 3; ++k) c[i * 3 + j] += a[i * 3 + k] * b[k * 3 + j];
  return c;
}
}  // namespace detail

// Writes A (row-major: a11, a12, a21, a22) and B (b1, b2) as out[0..5].
inline void secondOrderMap(double fn, double zeta, double Ts, double* out) noexcept {
  const double wn = 2.0 * M_PI * std::max(fn, 1e-6);
  zeta = std::max(zeta, 0.0);
  detail::Mat3 m{0.0, Ts, 0.0, -wn * wn * Ts, -2.0 * zeta * wn * Ts, wn * wn * Ts, 0.0, 0.0, 0.0};
  // Scaled until its norm is at most 1/2 (the squarings are clamped: a NaN or an absurd fn stays finite
  // in count and gives a NaN or a useless map, which the fit rejects).
  double norm = 0.0;
  for (double x : m) norm = std::max(norm, std::fabs(x));
  int squarings = 0;
  while (norm * 3.0 > 0.5 && squarings < 60) norm *= 0.5, ++squarings;
  const double scale = std::ldexp(1.0, -squarings);
  for (double& x : m) x *= scale;
  // exp by its Taylor series to the 16th power (below 1e-17 relative at norm 1/2).
  detail::Mat3 e{1, 0, 0, 0, 1, 0, 0, 0, 1}, term = e;
  for (int k = 1; k <= 16; ++k) {
    term = detail::mul3(term, m);
    for (double& x : term) x /= k;
    for (int i = 0; i < 9; ++i) e[i] += term[i];
  }
  for (int i = 0; i < squarings; ++i) e = detail::mul3(e, e);
  out[0] = e[0];
  out[1] = e[1];
  out[2] = e[3];
  out[3] = e[4];
  out[4] = e[2];
  out[5] = e[5];
}

}  // namespace pamc::model
