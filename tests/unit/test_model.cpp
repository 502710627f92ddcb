#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "model/effects/second_order.hpp"
#include "model/model.hpp"
#include "model/staged_simulation.hpp"

using namespace pamc::model;

namespace {
std::vector<double> ramp(double u0, double u1, int n) {
  std::vector<double> u(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) u[static_cast<size_t>(i)] = u0 + (u1 - u0) * i / (n - 1);
  return u;
}
}  // namespace

// beta = gamma = 0: h integrates alpha du exactly; aligned, in the same sample: h_k = alpha (u_k - u_0);
// eq. (6) as printed, one sample late: h_k = alpha (u_{k-1} - u_0).
TEST(BoucWen, LinearCaseIsExact) {
  BoucWenParams p{2.0, 0.7, 1.5, 0.8, 0.0, 0.0};
  for (const auto form : {OutputForm::Aligned, OutputForm::Printed}) {
    Model m(p);
    m.setOutputForm(form);
    const auto u = ramp(-1.0, 2.0, 301);
    const auto y = m.simulate(u, 1e-3);
    for (size_t k = 1; k < u.size(); ++k) {
      const double h = 0.8 * ((form == OutputForm::Aligned ? u[k] : u[k - 1]) - u[0]);
      ASSERT_NEAR(y[k], p.k * p.rho * u[k] + p.b + p.k * (1 - p.rho) * h, 1e-12) << outputFormName(form);
    }
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

// beta + gamma > 0 is not enough: with gamma < 0 the loop's end lies beyond the point from which a
// reversal turns back, and the first reversal of a sine diverges. boucWenBounded and boucWenStable
// refuse such a set (the fit never takes one); gamma = 0 is the edge and stays bounded.
TEST(BoucWen, NegativeGammaDivergesAtTheFirstReversalAndIsRefused) {
  const BoucWenParams bad{3.0, 0.7, -4.0, 1.0, 0.9, -0.3}, edge{3.0, 0.7, -4.0, 1.0, 0.9, 0.0};
  std::vector<double> u(20000);
  for (size_t i = 0; i < u.size(); ++i) u[i] = 1.5 * std::sin(2 * M_PI * 0.3 * i * 1e-3) + 0.2;
  double worst_bad = 0, worst_edge = 0;
  for (double v : Model(bad).simulate(u, 1e-3)) worst_bad = std::max(worst_bad, std::fabs(v));
  for (double v : Model(edge).simulate(u, 1e-3)) worst_edge = std::max(worst_edge, std::fabs(v));
  EXPECT_GT(worst_bad, 1e3);    // the model runs away
  EXPECT_LT(worst_edge, 20.0);  // |y| <= |k rho u| + |b| + |k (1 - rho)| / beta
  EXPECT_FALSE(boucWenBounded(bad));
  EXPECT_TRUE(boucWenBounded(edge));
  std::string why;
  EXPECT_FALSE(boucWenStable(bad, -10, 10, &why));
  EXPECT_NE(why.find("gamma >= 0"), std::string::npos) << why;
  EXPECT_TRUE(boucWenStable(edge, -10, 10));
}

namespace {
// The continuous Bouc-Wen model (m = 1) between two samples: dh/du = alpha - beta |h| - gamma sign(du) h
// along the straight line from u_{k-1} to u_k, by classical RK4 with n steps. Independent of
// boucWenNext; with 10 000 steps per sample it is exact far below the tolerances used here.
double continuousStep(const BoucWenParams& p, double h, double du, int n) {
  if (du == 0.0) return h;
  const double s = du > 0 ? 1.0 : -1.0;
  auto f = [&](double x) { return p.alpha - p.beta * std::fabs(x) - p.gamma * s * x; };
  const double dv = du / n;
  for (int i = 0; i < n; ++i) {
    const double k1 = f(h), k2 = f(h + 0.5 * dv * k1), k3 = f(h + 0.5 * dv * k2), k4 = f(h + dv * k3);
    h += dv / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
  }
  return h;
}

// Output of the continuous model sampled at the end of each sample, h_0 = 0: aligned, y_k = Y(u_k, h)
// with h carried over [u_{k-1}, u_k] first (the continuous model: both terms see u_k); printed (eq. 6 as
// printed), y_k from h before that increment.
std::vector<double> continuousOutput(const BoucWenParams& p, const std::vector<double>& u, int n_sub,
                                     OutputForm form = OutputForm::Aligned) {
  std::vector<double> y(u.size());
  double h = 0.0;
  for (size_t k = 0; k < u.size(); ++k) {
    const double h_next = continuousStep(p, h, u[k] - u[k == 0 ? 0 : k - 1], n_sub);
    y[k] = boucWenOutput(p, u[k], form == OutputForm::Aligned ? h_next : h);
    h = h_next;
  }
  return y;
}

Model inForm(const BoucWenParams& p, OutputForm f) {
  Model m(p);
  m.setOutputForm(f);
  return m;
}

// Random steps of up to 6 V, held 20-300 samples, random ramps and a fast sine burst; a fixed generator
// mapped by hand so the input is the same with any standard library.
std::vector<double> stepRichInput(int n) {
  std::mt19937 g(12345);
  auto uni = [&](double a, double b) { return a + (b - a) * (static_cast<double>(g() % 1000000u) / 1e6); };
  std::vector<double> u;
  double level = 0.0;
  while (static_cast<int>(u.size()) < n) {
    const int len = 20 + static_cast<int>(g() % 281u);
    const int kind = static_cast<int>(g() % 3u);
    if (kind == 0) {  // jump and hold
      level = uni(-3.0, 3.0);
      for (int i = 0; i < len; ++i) u.push_back(level);
    } else if (kind == 1) {  // ramp
      const double to = uni(-3.0, 3.0);
      for (int i = 1; i <= len; ++i) u.push_back(level + (to - level) * i / len);
      level = to;
    } else {  // sine burst around the level, 5-40 Hz at 1 kHz
      const double f = uni(5.0, 40.0), a = uni(0.2, 1.5);
      for (int i = 0; i < len; ++i) u.push_back(level + a * std::sin(2 * M_PI * f * i * 1e-3));
    }
  }
  u.resize(static_cast<size_t>(n));
  return u;
}

struct Err {
  double max = 0, rmse = 0;
};
Err compare(const std::vector<double>& a, const std::vector<double>& b) {
  Err e;
  for (size_t i = 0; i < a.size(); ++i) {
    const double d = std::fabs(a[i] - b[i]);
    e.max = std::max(e.max, d);
    e.rmse += d * d;
  }
  e.rmse = std::sqrt(e.rmse / static_cast<double>(a.size()));
  return e;
}

const BoucWenParams kConvergenceSets[] = {
    {-0.4684, -16.53, 16.1, 1.0, 1.7241, 0.3711},  // identified on the paper's rig (counter-clockwise)
    {5.0, 0.6, 20.0, 1.0, 0.8, 0.2},               // clockwise: k (1 - rho) > 0
    {9.0, 1.25, 18.0, 1.0, 0.35, 0.25},            // the emulator's truth
    {3.0, 0.5, 10.0, 2.0, 2.5, 1.5},               // alpha != 1, stiff: c |du| up to 24 per sample
    {6.0, 1.4, 15.0, 1.0, -0.3, 0.9},              // beta < 0 (softening branch), beta + gamma > 0
};
}  // namespace

// The discrete model is the continuous one sampled: on steps of several volts, ramps and fast sines it
// matches a fine RK4 solution of the continuous h-equation far below a position sensor's resolution.
TEST(BoucWen, ConvergesToContinuousModelOnSteps) {
  const auto u = stepRichInput(3000);
  for (const auto form : {OutputForm::Aligned, OutputForm::Printed}) {
    for (const auto& p : kConvergenceSets) {
      const auto y = inForm(p, form).simulate(u, 1e-3);
      const auto ref = continuousOutput(p, u, 10000, form);
      const Err e = compare(y, ref);
      SCOPED_TRACE(std::string(outputFormName(form)) + " k=" + std::to_string(p.k) + " rho=" + std::to_string(p.rho) +
                   " beta=" + std::to_string(p.beta));
      EXPECT_LT(e.max, 1e-3) << "rmse " << e.rmse;
      EXPECT_LT(e.rmse, 1e-4);
    }
  }
}

// Why the aligned form is the default: sampled at the end of each sample, the continuous model's two
// terms see the same input; eq. (6) as printed forms y_k from h before u_k's increment and misses the
// continuous output by k (1 - rho) dh at every step - millimetres at a jump of volts.
TEST(BoucWen, PrintedFormLagsTheContinuousModelAtSteps) {
  const auto u = stepRichInput(3000);
  const BoucWenParams p{9.0, 1.25, 18.0, 1.0, 0.35, 0.25};
  const auto ref = continuousOutput(p, u, 10000, OutputForm::Aligned);
  EXPECT_LT(compare(inForm(p, OutputForm::Aligned).simulate(u, 1e-3), ref).max, 1e-3);
  EXPECT_GT(compare(inForm(p, OutputForm::Printed).simulate(u, 1e-3), ref).max, 0.5);
  // Default: aligned.
  EXPECT_EQ(Model(p).outputForm(), OutputForm::Aligned);
  EXPECT_EQ(Model(p).simulate(u, 1e-3), inForm(p, OutputForm::Aligned).simulate(u, 1e-3));
}

// Slow inputs (the paper's 0.1 Hz sine, 1 kHz): per sample c |du| is a few 1e-3, the series branch of
// boucWenNext runs, and it is as exact there as the closed form.
TEST(BoucWen, SlowInputMatchesContinuousModel) {
  std::vector<double> u(20000);
  for (size_t i = 0; i < u.size(); ++i) u[i] = 2.9 * std::sin(2 * M_PI * 0.1 * static_cast<double>(i) * 1e-3) + 0.2;
  for (const auto& p : kConvergenceSets) {
    for (const auto form : {OutputForm::Aligned, OutputForm::Printed}) {
      const Err e = compare(inForm(p, form).simulate(u, 1e-3), continuousOutput(p, u, 200, form));
      EXPECT_LT(e.max, 1e-6) << "k=" << p.k << " " << outputFormName(form);
    }
  }
}

// BoucWenStep, the estimator's form for many states and one increment, equals boucWenNext to the bit:
// random parameter sets (also diverging ones and alpha = 0), increments of both signs and zero, states
// on both sides of h = 0, at 0, far out and NaN, with the side hint on either side.
TEST(BoucWen, StepForManyStatesEqualsBoucWenNextToTheBit) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int set = 0; set < 200; ++set) {
    BoucWenParams p{1.0, 0.0, 0.0, 3.0 * U(rng), 2.0 * U(rng), 2.0 * U(rng)};
    if (set % 17 == 0) p.alpha = 0.0;
    for (double du : {0.0, 1e-6, -1e-6, 0.01 * U(rng), 0.3 * U(rng), 5.0 * U(rng), 1e3, -1e3}) {
      const BoucWenStep step(p, du, set % 2 == 0 ? U(rng) : 0.0);
      for (double h : {0.0, -0.0, 1e-9, -1e-9, U(rng), 3.0 * U(rng), 1e9, -1e9, double(NAN)}) {
        const double f_h = set % 3 == 0 ? 0.0 : U(rng);
        const double want = boucWenNext(p, h, du, f_h, 1e-3), got = step(h, f_h, 1e-3);
        if (std::isnan(want)) {
          EXPECT_TRUE(std::isnan(got));
        } else {
          EXPECT_EQ(got, want) << "alpha " << p.alpha << " beta " << p.beta << " gamma " << p.gamma << " du " << du
                               << " h " << h;
        }
      }
    }
  }
}

// The step's series for (1 - exp(-y)) / y below |y| = kSeriesLimit (Estrin's scheme) against expm1:
// within 2e-12 relative over the whole range, and at 0 exactly 1.
TEST(BoucWen, SeriesIsWithinItsStatedAccuracy) {
  EXPECT_EQ(detail::boucWenSeries(0.0), 1.0);
  double worst = 0.0;
  for (int i = -1000; i <= 1000; ++i) {
    const double y = detail::kSeriesLimit * i / 1000.0 * (1.0 - 1e-12);
    if (y == 0.0) continue;
    const double exact = -std::expm1(-y) / y;
    worst = std::max(worst, std::fabs(detail::boucWenSeries(y) - exact) / exact);
  }
  EXPECT_LT(worst, 2e-12);
  EXPECT_GT(worst, 0.0);  // the series is an approximation: its error is measured, not hidden by rounding
}

// One increment against the closed form, across h = 0, both directions, and the pass-throughs.
TEST(BoucWen, StepIsClosedFormAcrossZero) {
  const BoucWenParams p{1.0, 0.0, 0.0, 1.0, 0.7, 0.4};
  // Rising from h0 = -0.5: dh/du = 1 - (gamma - beta) h = 1 + 0.3 h for h < 0 reaches 0 at
  // u0 = ln(1 / (1 - 0.15)) / 0.3, then dh/du = 1 - 1.1 h.
  const double v0 = std::log(1.0 / (1.0 - 0.3 * 0.5)) / 0.3;
  const double expect = (1.0 - std::exp(-1.1 * (2.0 - v0))) / 1.1;
  EXPECT_NEAR(boucWenNext(p, -0.5, 2.0, 0.0, 1e-3), expect, 1e-14);
  // Falling is the mirror image (odd symmetry of the equation).
  EXPECT_NEAR(boucWenNext(p, 0.5, -2.0, 0.0, 1e-3), -expect, 1e-14);
  // Not reaching zero: stays on its side's exponential.
  const double e2 = -0.5 + (1.0 - 0.3 * 0.5) * (std::exp(0.3 * 0.1) - 1.0) / 0.3;
  EXPECT_NEAR(boucWenNext(p, -0.5, 0.1, 0.0, 1e-3), e2, 1e-14);
  // A jump of 1e3 V lands on the bound alpha / (beta + gamma).
  EXPECT_NEAR(boucWenNext(p, -0.5, 1e3, 0.0, 1e-3), 1.0 / 1.1, 1e-12);
  // f_h is added as f_h Ts; du = 0 leaves h; NaN passes; a diverging set is clamped.
  EXPECT_DOUBLE_EQ(boucWenNext(p, 0.25, 0.0, 3.0, 1e-3), 0.253);
  EXPECT_TRUE(std::isnan(boucWenNext(p, NAN, 0.1, 0.0, 1e-3)));
  EXPECT_TRUE(std::isnan(boucWenNext(p, 0.1, NAN, 0.0, 1e-3)));
  EXPECT_TRUE(std::isnan(boucWenNext(p, 0.1, 0.0, NAN, 1e-3)));
  const BoucWenParams bad{1.0, 0.0, 0.0, 1.0, -2.0, -1.0};
  EXPECT_EQ(boucWenNext(bad, 0.1, 50.0, 0.0, 1e-3), 1e9);
  EXPECT_EQ(boucWenNext(bad, -0.1, -50.0, 0.0, 1e-3), -1e9);
  // alpha = 0 with h = 0 is a fixed point, even for a diverging c.
  EXPECT_EQ(boucWenNext({1.0, 0.0, 0.0, 0.0, -2.0, -1.0}, 0.0, 1e3, 0.0, 1e-3), 0.0);
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

// The mass-spring's one-sample map is the exact one for an input held over the sample: against a
// fine RK4 solution of y'' = wn^2 (in - y) - 2 zeta wn y', from under- to overdamped, slow to 100 Hz,
// at the sample times of a record and of a decimated one.
TEST(Effects, SecondOrderMapIsExactForAHeldInput) {
  for (double fn : {0.5, 8.0, 40.0, 100.0})
    for (double zeta : {0.02, 0.3, 1.0, 2.5})
      for (double Ts : {1e-3, 1.2e-2}) {
        double map[6];
        secondOrderMap(fn, zeta, Ts, map);
        const double wn = 2 * M_PI * fn;
        // Column by column: the responses to y = 1, to v = 1 and to in = 1.
        const double starts[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
        const double got[3][2] = {{map[0], map[2]}, {map[1], map[3]}, {map[4], map[5]}};
        for (int c = 0; c < 3; ++c) {
          double y = starts[c][0], v = starts[c][1];
          const double in = starts[c][2];
          auto f = [&](double yy, double vv) { return wn * wn * (in - yy) - 2 * zeta * wn * vv; };
          const int n = 20000;
          const double h = Ts / n;
          for (int i = 0; i < n; ++i) {
            const double k1y = v, k1v = f(y, v);
            const double k2y = v + 0.5 * h * k1v, k2v = f(y + 0.5 * h * k1y, v + 0.5 * h * k1v);
            const double k3y = v + 0.5 * h * k2v, k3v = f(y + 0.5 * h * k2y, v + 0.5 * h * k2v);
            const double k4y = v + h * k3v, k4v = f(y + h * k3y, v + h * k3v);
            y += h / 6 * (k1y + 2 * k2y + 2 * k3y + k4y);
            v += h / 6 * (k1v + 2 * k2v + 2 * k3v + k4v);
          }
          SCOPED_TRACE("fn " + std::to_string(fn) + " zeta " + std::to_string(zeta) + " Ts " + std::to_string(Ts));
          EXPECT_NEAR(got[c][0], y, 1e-9 * std::max(1.0, std::fabs(y)));
          EXPECT_NEAR(got[c][1], v, 1e-9 * std::max(1.0, std::fabs(v)));
        }
      }
}

// friction_hysteresis's step is exact for an input that moves monotonically within the sample: against
// a fine RK4 solution of dz/din = a g / (1 + a g), g = 1 - sign(din) z / zmax, over big and small steps.
TEST(Effects, FrictionHysteresisStepIsExactAlongTheInput) {
  const double zmax = 0.7, delta = 0.25, a = zmax / delta;
  Model m(BoucWenParams{1.0, 1.0, 0.0, 1.0, 0.0, 0.0});  // y_core = u
  m.addEffect("friction_hysteresis");
  m.setEffectParam("friction_hysteresis", "zmax", zmax);
  m.setEffectParam("friction_hysteresis", "delta", delta);
  const std::vector<double> u = {0.0, 0.3, 0.35, 1.5, 1.2, 1.19, -0.4, 0.2, 0.21, 3.0};
  const auto y = m.simulate(u, 1e-3);
  double z = 0.0;
  for (size_t k = 1; k < u.size(); ++k) {
    const double din = u[k] - u[k - 1], sgn = din > 0 ? 1.0 : -1.0;
    auto f = [&](double zz) {
      const double g = std::max(0.0, 1.0 - sgn * zz / zmax);
      return a * g / (1.0 + a * g);
    };
    const int n = 100000;
    const double h = din / n;
    for (int i = 0; i < n; ++i) {
      const double k1 = f(z), k2 = f(z + 0.5 * h * k1), k3 = f(z + 0.5 * h * k2), k4 = f(z + h * k3);
      z += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
    }
    EXPECT_NEAR(y[k], u[k] - z, 1e-9) << "sample " << k;
  }
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

// A richer form holds the forms it refines as special cases, so its box holds theirs where they share a
// parameter: diagnose carries the simpler form's fit into it by name, and a box narrower than that fit
// clamps it (muscle_balance's pre-sliding travel, boxed at 2 y-units against friction_hysteresis's 20:
// on the paper's u0 record friction_hysteresis's fitted 3.6 mm - the braid's 3 mm - went into the balance
// at 1.2 mm). Known and left: the balances' and hysteretic_spring's damping ratio, at most 1 against
// mass_spring's overdamped 3 (docs/MODELING.md).
TEST(Effects, ARicherFormsBoxHoldsTheFormsItRefines) {
  const std::vector<std::string> left = {"hysteretic_spring/mass_spring/zeta", "muscle_balance/mass_spring/zeta"};
  for (const auto& e : catalogue()) {
    const auto richer = e.make();
    for (const auto& r : richer->refines()) {
      for (const auto& rp : makeEffect(r)->params()) {
        for (const auto& ep : richer->params()) {
          if (ep.name != rp.name) continue;
          const std::string which = std::string(e.name) + "/" + r + "/" + ep.name;
          if (std::find(left.begin(), left.end(), which) != left.end()) continue;
          EXPECT_EQ(ep.unit, rp.unit) << which;
          EXPECT_LE(ep.lo, rp.lo) << which;
          EXPECT_GE(ep.hi, rp.hi) << which;
        }
      }
    }
  }
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

// StagedSimulation reruns only the stages a parameter acts in: on random structures from the whole
// catalogue (with a load column), with random parameters within their bounds and an input of slow
// drifts and large jumps, every run - a new point, each one-parameter change as Levenberg-Marquardt's
// Jacobian columns make them, a change of several - equals Model::simulate() to the bit, and a column
// of a core or an output parameter does not rerun the input effects.
TEST(StagedSimulation, EqualsSimulateToTheBitAndRerunsOnlyLaterStages) {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> U(0.0, 1.0);
  const size_t n = 3000;
  std::vector<double> u(n), load(n);
  double v = 2.0;
  for (size_t i = 0; i < n; ++i) {
    v += i % 400 == 0 ? 6.0 * (U(rng) - 0.5) : 0.02 * (U(rng) - 0.5);
    u[i] = std::clamp(v, -4.0, 8.0);
    load[i] = i < n / 2 ? 0.0 : 30.0 + 10.0 * U(rng);
  }
  const auto& cat = catalogue();
  int columns_core = 0, columns_output = 0, columns_input = 0;
  for (int trial = 0; trial < 30; ++trial) {
    Model m({4.0 + 4.0 * U(rng), 0.5 + 0.4 * U(rng), 15.0, 1.0, 0.3 + 0.5 * U(rng), 0.1 + 0.3 * U(rng)});
    for (const auto& e : cat) {
      if (U(rng) < 0.6) continue;
      try {
        m.addEffect(e.name);
      } catch (const std::exception&) {  // an alternative to one taken, or too many states
      }
    }
    std::vector<double> p = m.params();
    const auto specs = m.paramSpecs();
    for (size_t i = kBoucWenParams; i < p.size(); ++i) p[i] = specs[i].lo + (specs[i].hi - specs[i].lo) * U(rng);
    m.setParams(p);
    StagedSimulation sim;
    std::vector<double> y(n), ref(n);
    const double* lp = trial % 2 == 0 ? load.data() : nullptr;
    auto check = [&](const char* what) {
      sim.run(m, u.data(), lp, n, 1e-3, y.data());
      m.simulate(u.data(), lp, n, 1e-3, ref.data());
      for (size_t i = 0; i < n; ++i) {
        if (std::isnan(ref[i]))
          ASSERT_TRUE(std::isnan(y[i])) << m.describe() << " " << what << " sample " << i;
        else
          ASSERT_EQ(y[i], ref[i]) << m.describe() << " " << what << " sample " << i;
      }
    };
    check("first run");
    EXPECT_EQ(sim.lastStart(), 0);
    for (int it = 0; it < 2; ++it) {
      const std::vector<double> base = m.params();
      for (size_t k = 0; k < base.size(); ++k) {
        std::vector<double> q = base;
        q[k] *= 1.0 + 1e-3;
        q[k] += 1e-4;
        m.setParams(q);
        check("column");
        const int want = k < static_cast<size_t>(kBoucWenParams)       ? 1
                         : k < static_cast<size_t>(m.inputParamsEnd()) ? 0
                                                                       : 2;
        EXPECT_EQ(sim.lastStart(), want) << m.describe() << " parameter " << k;
        (want == 1 ? columns_core : want == 2 ? columns_output : columns_input)++;
      }
      std::vector<double> q = base;  // a trial step: every parameter a little
      for (size_t k = kBoucWenParams; k < q.size(); ++k) q[k] = specs[k].lo + (specs[k].hi - specs[k].lo) * U(rng);
      q[0] *= 1.01;
      m.setParams(q);
      check("new point");
      EXPECT_EQ(sim.lastStart(), m.inputParamsEnd() > kBoucWenParams ? 0 : 1);
    }
  }
  EXPECT_GT(columns_core, 100);
  EXPECT_GT(columns_output, 20);
  EXPECT_GT(columns_input, 20);
}
