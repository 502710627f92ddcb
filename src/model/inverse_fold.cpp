#include "model/inverse_fold.hpp"

#include <cmath>
#include <cstdio>
#include <vector>

namespace pamc::model {

InverseFold inverseFold(const Model& m, double u_lo, double u_hi) {
  constexpr int kBranch = 2000;  // samples per branch: the core is rate-independent, this is its resolution
  constexpr double kTs = 1e-3;
  InverseFold f;
  if (!(u_hi > u_lo)) return f;
  const std::size_t n = 4 * kBranch + 1;
  std::vector<double> u(n), u_eff(n), y(n);
  for (std::size_t i = 0; i < n; ++i) {
    const int k = static_cast<int>(i % (2 * kBranch)), x = k <= kBranch ? k : 2 * kBranch - k;
    u[i] = u_lo + (u_hi - u_lo) * x / kBranch;
  }
  const double rest = m.simulateInput(u.data(), nullptr, n, kTs, u_eff.data());
  m.simulateCore(rest, u_eff.data(), n, kTs, y.data());
  f.gain = (y[3 * kBranch] - y[2 * kBranch]) / (u_hi - u_lo);
  if (!std::isfinite(f.gain) || f.gain == 0.0) return f;
  for (std::size_t i = 2 * kBranch; i + 1 < n; ++i) {
    const double s = (y[i + 1] - y[i]) / (u[i + 1] - u[i]) / f.gain;
    if (s < f.least) f.least = s, f.at_u = u[i];
  }
  f.folds = f.least < 0.0;
  return f;
}

std::string describeInverseFold(const InverseFold& f) {
  char b[320];
  if (f.folds)
    std::snprintf(b, sizeof b,
                  "its inverse folds: along a branch its output turns against its command (slope %.3g of its settled "
                  "gain %.4g, at the command %.4g), so an inverse of it - the MBC's feedforward - jumps there",
                  f.least, f.gain, f.at_u);
  else
    std::snprintf(b, sizeof b,
                  "its inverse does not fold (its least slope along a branch %.3g of its settled gain %.4g)", f.least,
                  f.gain);
  return b;
}

}  // namespace pamc::model
