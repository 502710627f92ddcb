// The one-sample map of a mass on a spring and damper driven by an input, shared by mass_spring and
// force_loop: y'' = wn^2 (in - y) - 2 zeta wn y'. Semi-implicit Euler with sub-steps short against the
// period (stable and accurate at any fn), composed once into the exact linear map it amounts to over a
// sample, [y v]' = A [y v] + B in.
#pragma once

#include <algorithm>
#include <cmath>
#include <utility>

namespace pamc::model {

// Writes A (row-major: a11, a12, a21, a22) and B (b1, b2) as out[0..5].
inline void secondOrderMap(double fn, double zeta, double Ts, double* out) noexcept {
  const double wn = 2.0 * M_PI * std::max(fn, 1e-6);
  zeta = std::max(zeta, 0.0);
  // Clamped before the conversion, so a huge fn cannot overflow the int (NaN takes one step).
  const double steps = std::ceil(wn * Ts / 0.05);
  const int n = steps >= 1.0 ? (steps < 2000.0 ? static_cast<int>(steps) : 2000) : 1;
  const double h = Ts / n;
  auto run = [&](double y, double v, double in) {
    for (int i = 0; i < n; ++i) {
      v += h * (wn * wn * (in - y) - 2.0 * zeta * wn * v);
      y += h * v;
    }
    return std::pair<double, double>(y, v);
  };
  const auto e1 = run(1, 0, 0), e2 = run(0, 1, 0), b = run(0, 0, 1);
  out[0] = e1.first;
  out[1] = e2.first;
  out[2] = e1.second;
  out[3] = e2.second;
  out[4] = b.first;
  out[5] = b.second;
}

}  // namespace pamc::model
