// One effect on its own (tests/unit/test_muscle_balance.cpp, test_pneumatic_balance.cpp): a core that
// passes its input through, reproducible ramps and holds to drive it, the RMS of a difference.
#pragma once

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "model/model.hpp"

namespace pamc::test {

constexpr double kEffectTs = 1e-3;

// y = the effect alone: a core with rho = 1, k = 1, b = 0 passes the input through.
inline model::Model alone(const std::string& effect, const std::map<std::string, double>& params) {
  model::Model m({1.0, 1.0, 0.0, 1.0, 0.3, 0.3});
  m.addEffect(effect);
  for (const auto& [k, v] : params) m.setEffectParam(effect, k, v);
  return m;
}

// Random ramps and holds over [lo, hi], reproducible.
inline std::vector<double> rampsAndHolds(double lo, double hi, size_t n, unsigned seed) {
  std::vector<double> u(n);
  unsigned s = seed;
  auto next = [&s] { return (s = s * 1103515245u + 12345u) / 4294967296.0; };
  double v = 0.5 * (lo + hi), target = v, rate = 0.0;
  for (size_t i = 0; i < n; ++i) {
    if (std::fabs(target - v) < 1e-9 && next() < 0.002) {
      target = lo + (hi - lo) * next();
      rate = (0.5 + 20.0 * next()) * kEffectTs;
    }
    v += std::clamp(target - v, -rate, rate);
    u[i] = v;
  }
  return u;
}

inline double rms(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / static_cast<double>(a.size()));
}

}  // namespace pamc::test
