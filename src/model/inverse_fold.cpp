#include "model/inverse_fold.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

namespace pamc::model {

InverseFold inverseFold(const Model& m, double u_lo, double u_hi) {
  constexpr int kBranch = 2000;  // samples per branch: the core is rate-independent, this is its resolution
  constexpr double kTs = 1e-3;
  InverseFold f;
  // The core's input range: the commands through the input effects at rest. Their dynamics (pressure_lag)
  // are left out: swept, a lag's input goes on past each reversal of the command, which is no fold.
  double first = 0.0;  // simulateInput's one sample, not used: its return value is the input at rest
  double e_lo = m.simulateInput(&u_lo, nullptr, 1, kTs, &first);
  double e_hi = m.simulateInput(&u_hi, nullptr, 1, kTs, &first);
  if (e_lo > e_hi) std::swap(e_lo, e_hi);
  if (!(e_hi > e_lo)) return f;
  const std::size_t n = 4 * kBranch + 1;  // up, down, up, down
  std::vector<double> e(n), y(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int k = static_cast<int>(i % (2 * kBranch)), x = k <= kBranch ? k : 2 * kBranch - k;
    e[i] = e_lo + (e_hi - e_lo) * x / kBranch;
  }
  m.simulateCore(e[0], e.data(), n, kTs, y.data());
  f.gain = (y[3 * kBranch] - y[2 * kBranch]) / (e_hi - e_lo);
  if (!std::isfinite(f.gain) || f.gain == 0.0) return f;
  for (std::size_t i = 2 * kBranch; i + 1 < n; ++i) {
    const double s = (y[i + 1] - y[i]) / (e[i + 1] - e[i]) / f.gain;
    if (s < f.least) f.least = s, f.at_input = e[i];
  }
  f.folds = f.least < 0.0;
  return f;
}

std::string describeInverseFold(const InverseFold& f) {
  char b[320];
  if (f.folds)
    std::snprintf(b, sizeof b,
                  "its inverse folds: along a branch its output turns against its command (slope %.3g of its settled "
                  "gain %.4g, at its input %.4g), so an inverse of it - the MBC's feedforward - jumps there",
                  f.least, f.gain, f.at_input);
  else
    std::snprintf(b, sizeof b,
                  "its inverse does not fold (its least slope along a branch %.3g of its settled gain %.4g)", f.least,
                  f.gain);
  return b;
}

}  // namespace pamc::model
