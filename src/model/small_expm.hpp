// The exponential of a small square matrix (row-major std::array of N x N), by scaling until its largest
// entry is at most `limit`, its Taylor series to `terms` terms, and squaring back: exact to rounding for
// the 3x3 and 4x4 maps of the effects that ring (second_order.hpp, hysteretic_spring.cpp). No allocation.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>

namespace pamc::model {

template <int N>
using SmallMat = std::array<double, static_cast<std::size_t>(N* N)>;

template <int N>
SmallMat<N> smallMul(const SmallMat<N>& a, const SmallMat<N>& b) noexcept {
  SmallMat<N> c{};
  for (int i = 0; i < N; ++i)
    for (int k = 0; k < N; ++k)
      for (int j = 0; j < N; ++j) c[i * N + j] += a[i * N + k] * b[k * N + j];
  return c;
}

// The squarings are clamped: a NaN or an absurd entry stays finite in count and gives a NaN or a useless
// map, which a fit rejects.
template <int N>
SmallMat<N> smallExpm(SmallMat<N> m, double limit, int terms) noexcept {
  double norm = 0.0;
  for (double x : m) norm = std::max(norm, std::fabs(x));
  int squarings = 0;
  while (norm > limit && squarings < 60) norm *= 0.5, ++squarings;
  const double scale = std::ldexp(1.0, -squarings);
  for (double& x : m) x *= scale;
  SmallMat<N> e{}, term{};
  for (int i = 0; i < N; ++i) e[i * N + i] = term[i * N + i] = 1.0;
  for (int k = 1; k <= terms; ++k) {  // term = m^k / k!
    term = smallMul<N>(term, m);
    for (double& x : term) x /= k;
    for (std::size_t i = 0; i < e.size(); ++i) e[i] += term[i];
  }
  for (int s = 0; s < squarings; ++s) e = smallMul<N>(e, e);
  return e;
}

}  // namespace pamc::model
