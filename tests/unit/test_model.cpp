#include <gtest/gtest.h>

#include <cmath>

#include "model/model.hpp"

using namespace pamc::model;

namespace {
std::vector<double> ramp(double u0, double u1, int n) {
  std::vector<double> u(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) u[static_cast<size_t>(i)] = u0 + (u1 - u0) * i / (n - 1);
  return u;
}
}  // namespace

// beta = gamma = 0: h integrates alpha du exactly, one sample late (eq. 6): h_k = alpha (u_{k-1} - u_0).
TEST(BoucWen, LinearCaseIsExact) {
  BoucWenParams p{2.0, 0.7, 1.5, 0.8, 0.0, 0.0};
  Model m(p);
  const auto u = ramp(-1.0, 2.0, 301);
  const auto y = m.simulate(u, 1e-3);
  for (size_t k = 1; k < u.size(); ++k) {
    const double h = 0.8 * (u[k - 1] - u[0]);
    ASSERT_NEAR(y[k], p.k * p.rho * u[k] + p.b + p.k * (1 - p.rho) * h, 1e-12);
  }
}

// Rising input from h = 0 (u_dot > 0, h >= 0): dh/du = alpha - (beta + gamma) h, so
// h(u) = alpha/(beta+gamma) (1 - exp(-(beta+gamma)(u - u0))). Falling afterwards with h > 0:
// dh/du = alpha - (beta - gamma) h.
TEST(BoucWen, MatchesClosedFormOnMonotonicBranches) {
  BoucWenParams p{1.0, 0.0, 0.0, 1.0, 0.5, 0.3};  // y = h
  Model m(p);
  const int n = 200001;
  auto u = ramp(0.0, 3.0, n);
  auto y = m.simulate(u, 1e-3);
  const double s = p.beta + p.gamma;
  const double h_top = p.alpha / s * (1 - std::exp(-s * 3.0));
  EXPECT_NEAR(y.back(), h_top, 1e-4);
  EXPECT_NEAR(y[static_cast<size_t>(n / 3)], p.alpha / s * (1 - std::exp(-s * 1.0)), 1e-4);
  // Now fall by 1 V from the top.
  std::vector<double> u2 = u;
  auto down = ramp(3.0, 2.0, n);
  u2.insert(u2.end(), down.begin() + 1, down.end());
  auto y2 = m.simulate(u2, 1e-3);
  const double d = p.beta - p.gamma;
  // u falls by 1 V: h(u) = a/d + (h0 - a/d) exp(-d (u - u0)) with u - u0 = -1.
  EXPECT_NEAR(y2.back(), p.alpha / d + (h_top - p.alpha / d) * std::exp(d), 1e-4);
}

// (alpha, k(1-rho)) -> (c alpha, k(1-rho)/c) leaves the output unchanged: why alpha is fixed.
TEST(BoucWen, ScaleInvariance) {
  BoucWenParams p{6.0, 1.25, 18.0, 1.0, 0.35, 0.25};
  const double c = 2.5;
  const double a = p.k * p.rho, hk = p.k * (1 - p.rho);
  BoucWenParams q = p;
  q.alpha = c * p.alpha;
  q.k = a + hk / c;
  q.rho = a / q.k;
  std::vector<double> u(20000);
  for (size_t i = 0; i < u.size(); ++i) u[i] = 2.9 * std::sin(2 * M_PI * 0.1 * i * 1e-3) + 0.2;
  const auto y1 = Model(p).simulate(u, 1e-3);
  const auto y2 = Model(q).simulate(u, 1e-3);
  for (size_t i = 0; i < u.size(); i += 97) ASSERT_NEAR(y1[i], y2[i], 1e-9);
}

TEST(BoucWen, LargeCommandJumpStaysBounded) {
  BoucWenParams p{6.0, 1.25, 18.0, 1.0, 0.9, 0.8};
  Model m(p);
  std::vector<double> u = {0, 5, -5, 5, -5, 5};
  const auto y = m.simulate(u, 1e-3);
  for (double v : y) EXPECT_TRUE(std::isfinite(v));
  // |h| stays within the Bouc-Wen bound alpha / (beta + gamma) after the jumps (sub-stepping).
  Model::State st;
  StepContext c;
  m.init(st, 0.0, c);
  for (double v : u) m.step(st, v, c);
  EXPECT_LE(std::fabs(st.h), 1.0 / (0.9 + 0.8) + 1e-9);  // alpha / (beta + gamma)
}

TEST(Effects, PressureLagIsFirstOrder) {
  Model m(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});  // y = u_eff
  m.addEffect("pressure_lag");
  m.setEffectParam("pressure_lag", "tau", 0.05);
  m.setEffectParam("pressure_lag", "slew", 1000.0);
  std::vector<double> u(400, 1.0);
  u[0] = 0.0;
  const auto y = m.simulate(u, 1e-3);
  // Sample k (k >= 1) has seen k samples of the step: 1 - exp(-k Ts / tau).
  for (int k : {1, 50, 100, 300}) EXPECT_NEAR(y[static_cast<size_t>(k)], 1 - std::exp(-k * 1e-3 / 0.05), 1e-12);
}

TEST(Effects, MassSpringOvershootAndGain) {
  Model m(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});
  m.addEffect("mass_spring");
  m.setEffectParam("mass_spring", "fn", 5.0);
  m.setEffectParam("mass_spring", "zeta", 0.2);
  std::vector<double> u(3000, 1.0);
  u[0] = 0.0;
  const auto y = m.simulate(u, 1e-3);
  double peak = 0;
  for (double v : y) peak = std::max(peak, v);
  EXPECT_NEAR(peak - 1.0, std::exp(-M_PI * 0.2 / std::sqrt(1 - 0.04)), 0.02);  // 52.7 %
  EXPECT_NEAR(y.back(), 1.0, 0.01);
}

TEST(Effects, SaturationLoadAndFriction) {
  Model m(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});
  m.addEffect("saturation");
  m.setEffectParam("saturation", "knee", 10.0);
  m.setEffectParam("saturation", "width", 5.0);
  auto y = m.simulate({5.0, 9.9, 10.0, 100.0}, 1e-3);
  EXPECT_DOUBLE_EQ(y[0], 5.0);
  EXPECT_DOUBLE_EQ(y[1], 9.9);
  EXPECT_NEAR(y[3], 15.0, 1e-9);  // levels off at knee + width

  Model l(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});
  l.addEffect("load");
  l.setEffectParam("load", "compliance", 0.1);
  EXPECT_TRUE(l.needsLoad());
  const auto yl = l.simulate({2.0, 2.0}, 1e-3, {0.0, 40.0});
  EXPECT_DOUBLE_EQ(yl[0], 2.0);
  EXPECT_DOUBLE_EQ(yl[1], 2.0 - 4.0);

  // Friction: a slow full cycle leaves a loop of height 2 zmax between the branches.
  Model f(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});
  f.addEffect("friction_hysteresis");
  f.setEffectParam("friction_hysteresis", "zmax", 0.5);
  f.setEffectParam("friction_hysteresis", "delta", 0.01);
  std::vector<double> u;
  for (int i = 0; i <= 1000; ++i) u.push_back(10.0 * i / 1000);
  for (int i = 1000; i >= 0; --i) u.push_back(10.0 * i / 1000);
  const auto yf = f.simulate(u, 1e-3);
  const double up = yf[500], down = yf[1001 + 500];
  EXPECT_NEAR(down - up, 1.0, 0.02);
}

TEST(Effects, CatalogueErrorsListKnownNames) {
  Model m;
  try {
    m.addEffect("no_such_effect");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("pressure_lag"), std::string::npos);
  }
  m.addEffect("mass_spring");
  EXPECT_THROW(m.addEffect("mass_spring"), std::invalid_argument);
}

TEST(Effects, ChainOrderDoesNotDependOnInsertionOrder) {
  Model a, b;
  a.addEffect("mass_spring");
  a.addEffect("pressure_lag");
  a.addEffect("saturation");
  b.addEffect("saturation");
  b.addEffect("pressure_lag");
  b.addEffect("mass_spring");
  EXPECT_EQ(a.effectNames(), b.effectNames());
  EXPECT_EQ(a.effectNames().front(), "pressure_lag");  // input stage first
}
