// Tests of the test oracle (oracle_sim.hpp): its integrator converges, its core meets the Bouc-Wen
// closed form, every effect shows its characteristic signature, the noise is what was configured, and
// the pre-decided cases are well-formed. Every expectation compares with a number worked out here, not
// with the oracle's own output, so each can fail.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <set>
#include <sstream>

#include "oracle_sim.hpp"

using namespace pamc::oracle;

namespace {

constexpr double Ts = 1e-3;

SimOptions clean() {
  SimOptions o;
  o.noise_std = 0.0;
  o.quantum = 0.0;
  return o;
}

std::vector<double> yClean(const Core& c, const std::vector<EffectSpec>& e, const std::vector<double>& u,
                           SimOptions o = clean(), const std::vector<double>* load = nullptr) {
  return simulate(c, e, u, load, o).y_clean;
}

Core linearCore() {  // rho = 1: no hysteresis, y = k u + b
  Core c;
  c.k = 6.5;
  c.rho = 1.0;
  c.b = 20.0;
  return c;
}

// n0 samples at a, then n1 at b.
std::vector<double> step(size_t n0, double a, size_t n1, double b) {
  std::vector<double> u(n0, a);
  u.insert(u.end(), n1, b);
  return u;
}

// Linear ramp from a to b over n samples (inclusive ends).
std::vector<double> ramp(double a, double b, size_t n) {
  std::vector<double> u(n);
  for (size_t i = 0; i < n; ++i) u[i] = a + (b - a) * static_cast<double>(i) / static_cast<double>(n - 1);
  return u;
}

// Time at which y first crosses `level` after sample `from` (the last before a step), interpolated between
// the ends of the samples (sample k ends at (k + 1) Ts), from the start of the step sample.
double crossingTime(const std::vector<double>& y, size_t from, double level) {
  for (size_t k = from; k + 1 < y.size(); ++k) {
    if ((y[k] - level) * (y[k + 1] - level) <= 0.0 && y[k + 1] != y[k]) {
      const double f = (level - y[k]) / (y[k + 1] - y[k]);
      return (static_cast<double>(k - from) + f) * Ts;
    }
  }
  return NAN;
}

double maxAbsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  double m = 0.0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, std::fabs(a[i] - b[i]));
  return m;
}

std::vector<EffectSpec> many() {
  return {parseEffect("delay:d=0.0234"),
          parseEffect("dead_band:threshold=-2"),
          parseEffect("pressure_lag:tau=0.03,slew=200"),
          parseEffect("asymmetry:gain=1.5,w_up=1,w_down=0.3"),
          parseEffect("saturation:knee=35,width=6"),
          parseEffect("creep:fraction=0.08,tau=2"),
          parseEffect("friction_hysteresis:zmax=0.5,delta=0.2"),
          parseEffect("mass_spring:fn=6,zeta=0.1"),
          parseEffect("warm_up:tau=5,gain=0.1,shift=0.5")};
}

}  // namespace

// ---- the integrator ---------------------------------------------------------------------------

TEST(OracleIntegrator, TighterToleranceAndHalfStepChangeFarLessThanNoise) {
  const auto u = makeSignal("mixed", 8.0, Ts, 7);
  const double noise = std::sqrt(0.005 * 0.005 + 0.001 * 0.001 / 12.0);
  for (const auto& effects : {std::vector<EffectSpec>{}, many(),
                              std::vector<EffectSpec>{parseEffect("force_loop:fn=8,zeta=0.2,zmax=0.6,delta=0.05")}}) {
    const auto base = yClean(Core{}, effects, u);
    SimOptions tight = clean();
    tight.rtol = tight.atol = 1e-12;
    SimOptions half = clean();
    half.max_step = 0.5e-3;
    SimOptions tiny = clean();
    tiny.max_step = 1e-5;  // far below what the tolerance picks: a check independent of the error estimate
    EXPECT_LT(maxAbsDiff(base, yClean(Core{}, effects, u, tight)), 0.1 * noise);
    EXPECT_LT(maxAbsDiff(base, yClean(Core{}, effects, u, half)), 0.1 * noise);
    EXPECT_LT(maxAbsDiff(base, yClean(Core{}, effects, u, tiny)), 0.1 * noise);
  }
}

// ---- muscle_balance ---------------------------------------------------------------------------

namespace {

// The law muscle_balance is meant to have (oracle_sim.cpp), written here once more: the position at
// rest at stage input s with friction force f (+: opposing a rise), by bisection.
struct BalanceLaw {
  double w, L, f0, fp;
  double rest(double s, double f) const {
    auto g = [&](double x) { return (s + w) * std::exp(-x / L) - w - x - f; };
    double a = -200.0, b = 200.0;
    for (int i = 0; i < 200; ++i) {
      const double m = 0.5 * (a + b);
      (g(m) > 0.0 ? a : b) = m;
    }
    return 0.5 * (a + b);
  }
  double level(double s) const { return f0 + fp * std::max(s + w, 0.0); }
};

EffectSpec balance(const std::string& extra) { return parseEffect("muscle_balance:fn=8,zeta=0.7,w=10,L=60" + extra); }

// The output where the command first crosses `level` going in `dir` (+1 up, -1 down) after sample `from`.
double atCrossing(const std::vector<double>& u, const std::vector<double>& y, size_t from, double level, int dir) {
  for (size_t k = from; k + 1 < u.size(); ++k)
    if (dir * (u[k] - level) <= 0.0 && dir * (u[k + 1] - level) > 0.0) return y[k];
  return NAN;
}

}  // namespace

TEST(OracleBalance, AtRestTheForceBalanceHolds) {
  const BalanceLaw law{10.0, 60.0, 0.2, 0.01};
  const auto u = step(500, 0.0, 3000, 2.0);  // s = 6.5 u + 20 (linear core)
  const auto y = yClean(linearCore(), {balance("")}, u);
  EXPECT_NEAR(y[0], law.rest(20.0, 0.0), 1e-9);
  EXPECT_NEAR(y.back(), law.rest(33.0, 0.0), 1e-6);
  EXPECT_GT(std::fabs(y.back() - 33.0), 1.0);  // the map is felt
  // With friction, after a slow rise the payload rests within the friction band, short of the free balance.
  auto v = ramp(0.0, 2.0, 10000);
  v.insert(v.end(), 3000, 2.0);
  const auto yf = yClean(linearCore(), {balance(",f0=0.2,fp=0.01,k_slip=2,spread=8")}, v);
  const double n = law.level(33.0), lo = law.rest(33.0, n), hi = law.rest(33.0, -n);
  EXPECT_GE(yf.back(), lo - 1e-6);
  EXPECT_LE(yf.back(), hi + 1e-6);
  EXPECT_LT(yf.back(), law.rest(33.0, 0.0) - 0.25 * (hi - lo) / 2.0);
  EXPECT_LT(std::fabs(yf.back() - yf[yf.size() - 500]), 1e-6);  // at rest
}

TEST(OracleBalance, RestsOnAStopWhenPushedIntoIt) {
  const BalanceLaw law{10.0, 60.0, 0.0, 0.0};
  // u = 3: s = 39.5, the stop about 1.5 mm short of the free balance
  const double top = std::round(law.rest(39.5, 0.0) - 1.5);
  const auto u = step(500, 0.0, 2000, 3.0);
  const auto free = yClean(linearCore(), {balance("")}, u);
  const auto y = yClean(linearCore(), {balance(",hi=" + std::to_string(top))}, u);
  const auto hit =
      static_cast<size_t>(std::find_if(y.begin(), y.end(), [&](double v) { return v >= top - 1e-9; }) - y.begin());
  ASSERT_LT(hit, y.size());
  EXPECT_GT(free[hit] - free[hit - 1], 1e-3);                                 // still moving fast when it arrives
  for (size_t k = hit; k < y.size(); ++k) ASSERT_NEAR(y[k], top, 1e-9) << k;  // rests, no bounce
  for (size_t k = 0; k < hit; ++k) ASSERT_NEAR(y[k], free[k], 1e-9) << k;     // untouched before
  // Pushed down onto the lower stop it rests there; pulled off, it leaves for its free balance.
  const double bottom = std::round(law.rest(13.5, 0.0) + 1.0);  // u = -1: s = 13.5
  auto d = step(500, 0.0, 2000, -1.0);
  d.insert(d.end(), 2000, 0.0);
  const auto yd = yClean(linearCore(), {balance(",lo=" + std::to_string(bottom))}, d);
  for (size_t k = 1000; k < 2500; ++k) ASSERT_NEAR(yd[k], bottom, 1e-9) << k;
  EXPECT_GT(yd[2600], bottom + 0.5);
  EXPECT_NEAR(yd.back(), law.rest(20.0, 0.0), 1e-6);
}

TEST(OracleBalance, FrictionLoopWidensWithThePressure) {
  // Slow triangles over 2 V at a low and a high pressure; the loop's width where the command crosses the
  // middle is the friction band's, x(s, -N(s)) - x(s, +N(s)), N = f0 + fp (s + w) with all elements slipped.
  const BalanceLaw law{10.0, 60.0, 0.2, 0.01};
  double width[2], expected[2];
  for (int j = 0; j < 2; ++j) {
    const double lo = j == 0 ? -1.5 : 2.5, mid = lo + 1.0, s = 6.5 * mid + 20.0;
    const auto u =
        makeSignal("triangle:f=0.02,lo=" + std::to_string(lo) + ",hi=" + std::to_string(lo + 2.0), 100.0, Ts, 1);
    const auto y = yClean(linearCore(), {balance(",f0=0.2,fp=0.01,k_slip=2,spread=8")}, u);
    // the first fall and the second rise: the first rise started from unloaded elements
    expected[j] = law.rest(s, -law.level(s)) - law.rest(s, law.level(s));
    width[j] = atCrossing(u, y, 25000, mid, -1) - atCrossing(u, y, 50000, mid, +1);
    std::printf("loop at s = %.2f mm: width %.4f mm, the band's %.4f mm\n", s, width[j], expected[j]);
    EXPECT_NEAR(width[j], expected[j], 0.03 * expected[j]) << j;
  }
  EXPECT_GT(width[1], 1.2 * width[0]);
  EXPECT_NEAR(width[1] / width[0], expected[1] / expected[0], 0.03 * expected[1] / expected[0]);
}

TEST(OracleBalance, TheGuidesFrictionBuildsUpWithTheSlidingSpeed) {
  // A slow triangle over 2 V slides at 6.5 x 0.08 = 0.52 mm/s (a map of 10 m: nearly linear); the guide
  // widens the loop by 2 fg (1 - exp(-v / vg)) at the crossing, beside the payload's own lag (taken out).
  const auto u = makeSignal("triangle:f=0.02,lo=-1,hi=1", 100.0, Ts, 1);
  auto width = [&](const std::string& guide) {
    const auto y = yClean(linearCore(), {parseEffect("muscle_balance:fn=8,zeta=0.7,w=10,L=10000" + guide)}, u);
    return atCrossing(u, y, 25000, 0.0, -1) - atCrossing(u, y, 50000, 0.0, +1);
  };
  const double lag = width(""), v = 0.52 / (1.0 + 30.0 / 10000.0);
  for (double vg : {0.52, 0.052}) {
    const double expected = 2.0 * 0.3 * (1.0 - std::exp(-v / vg));
    const double got = width(",fg=0.3,vg=" + std::to_string(vg)) - lag;
    std::printf("guide, vg %.3f mm/s: %.4f mm, expected %.4f\n", vg, got, expected);
    EXPECT_NEAR(got, expected, 0.03 * expected) << vg;
  }
}

TEST(OracleBalance, IntegrationConverges) {
  // Over a wide range, with friction and both stops met: 1e-11 against 1e-13, and steps of at most 10 us.
  const auto u =
      makeSignal("steps:lo=-3.5,hi=4,min=0.3,max=1.5,dur=5+multisine:fmin=0.1,fmax=4,n=15,lo=-3.5,hi=4", 10.0, Ts, 3);
  const std::vector<EffectSpec> e = {
      parseEffect("muscle_balance:fn=6,zeta=0.3,w=15,L=100,f0=0.15,fp=0.008,k_slip=3,spread=10,lo=2,hi=28")};
  const double noise = std::sqrt(0.005 * 0.005 + 0.001 * 0.001 / 12.0);
  const auto base = yClean(Core{}, e, u);
  SimOptions fine = clean();
  fine.rtol = fine.atol = 1e-13;
  SimOptions tiny = clean();
  tiny.max_step = 1e-5;
  EXPECT_LT(maxAbsDiff(base, yClean(Core{}, e, u, fine)), 1e-3 * noise);
  EXPECT_LT(maxAbsDiff(base, yClean(Core{}, e, u, tiny)), 1e-3 * noise);
  EXPECT_GT(std::count_if(base.begin(), base.end(), [](double v) { return v == 2.0; }), 50);
  EXPECT_GT(std::count_if(base.begin(), base.end(), [](double v) { return v == 28.0; }), 50);
}

TEST(OracleBalance, IsAnAlternativeOfTheOtherPayloads) {
  EXPECT_THROW(validateEffects({parseEffect("muscle_balance"), parseEffect("force_loop")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("muscle_balance"), parseEffect("mass_spring")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("muscle_balance:lo=3,hi=2")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("muscle_balance:L=1")}), std::invalid_argument);
}

// ---- pneumatic_balance ------------------------------------------------------------------------

namespace {

// pneumatic_balance's air written here once more (README): absolute pressure P = p + w + span, the volume
// over V0 of the exponential map, the choked nozzle's rate.
struct AirLaw {
  double w, span, supply, rate, vent, swell, n, L;
  double absolute(double p) const { return p + w + span; }
  double volume(double x) const { return 1.0 + swell * L * (1.0 - std::exp(-x / L)); }
  // dP/dt / P when venting choked at full opening: q = -vent rate P / P_s, P' = n q / v.
  double chokedVentRate(double x) const { return n * vent * rate / ((supply + span) * volume(x)); }
};

EffectSpec pneumatic(const std::string& extra) {
  return parseEffect("pneumatic_balance:fn=8,zeta=0.7,w=10,L=60,rate=400,vent=0.5,span=14,supply=100" + extra);
}

}  // namespace

TEST(OraclePneumatic, ChokedVentingDecaysTheAbsolutePressureExponentially) {
  // Volume fixed (swell 0): from p = 39.5 (u = 3) the setpoint drops far below (u = -8: y = -32), the
  // regulator opens fully to the atmosphere, and while P_a / P < 0.528 the nozzle is choked:
  // P' = -n vent rate P / (P_s v), P = P_0 exp(-r t). Below the choke the flow falls: slower than that.
  const AirLaw law{10.0, 14.0, 100.0, 400.0, 0.5, 0.0, 1.3, 60.0};
  const double r = law.chokedVentRate(0.0);
  Stepper st(linearCore(), {pneumatic(",swell=0,n=1.3,band=1")}, clean());
  st.reset(3.0);
  EXPECT_NEAR(st.pressure(), 39.5, 1e-12);
  std::vector<double> P;
  for (int k = 0; k < 1500; ++k) {
    st.step(-8.0);
    P.push_back(law.absolute(st.pressure()));
  }
  const double choke = law.span / 0.5282817877171743;  // (2 / 2.4)^3.5
  int checked = 0, slower = 0;
  for (size_t k = 2; k + 1 < P.size(); ++k) {
    const double expected = P[1] * std::exp(-r * static_cast<double>(k - 1) * Ts);
    if (P[k] > choke * 1.001) {
      ASSERT_NEAR(P[k], expected, 1e-7 * expected) << k;
      ++checked;
    } else if (P[k] < choke * 0.99 && P[k - 1] - law.span > 0.5) {
      // the rate of decay per sample below the choke is less than the choked one
      EXPECT_GT(P[k + 1] / P[k], std::exp(-r * Ts)) << k;
      ++slower;
    }
  }
  EXPECT_GT(checked, 300);
  EXPECT_GT(slower, 100);
  EXPECT_NEAR(P.back(), law.span, 1e-6);  // at the atmosphere: gauge zero at p = -w
  EXPECT_GE(P.back(), law.span - 1e-9);
}

TEST(OraclePneumatic, AHeldSetpointSettlesAtThePressureAndTheStaticBalance) {
  // A frictionless payload, a volume that grows: the pressure settles at the setpoint (the regulator's
  // opening (y - p) / band closes there) and the payload at the map's balance F(p, x) = x, filling and venting.
  const BalanceLaw law{10.0, 60.0, 0.0, 0.0};
  Stepper st(linearCore(), {pneumatic(",swell=0.02,n=1.25,band=2")}, clean());
  st.reset(0.0);  // y = 20
  EXPECT_NEAR(st.clean(), law.rest(20.0, 0.0), 1e-9);
  for (const auto& [u, y] : std::vector<std::pair<double, double>>{{2.0, 33.0}, {-1.0, 13.5}, {4.0, 46.0}}) {
    double early = 0.0;
    for (int k = 0; k < 3000; ++k) {
      st.step(u);
      if (k == 20) early = st.pressure();
    }
    EXPECT_GT(std::fabs(early - y), 0.5) << u;  // the pressure takes its time
    EXPECT_NEAR(st.pressure(), y, 1e-6) << u;
    EXPECT_NEAR(st.clean(), law.rest(y, 0.0), 1e-6) << u;
    EXPECT_GT(std::fabs(st.clean() - y), 1.0) << u;  // the map is felt
  }
}

TEST(OraclePneumatic, AContractionAtAClosedValveFollowsThePolytrope) {
  // The valve's opening held at zero (setpoint = pressure): P V^n stays constant as the muscle contracts
  // (the pressure falls) and extends (it rises). The law's rate integrated along x(t) by RK4 here.
  const AirLaw law{10.0, 14.0, 100.0, 400.0, 0.5, 0.03, 1.25, 60.0};
  const PneumaticAir air = pneumaticAir(pneumatic(",swell=0.03,n=1.25,band=1"));
  for (double speed : {150.0, -150.0}) {  // mm/s over 0.2 s: 30 mm
    const double x0 = speed > 0 ? -5.0 : 25.0;
    auto rate = [&](double t, double p) { return air.pressureRate(p, p, x0 + speed * t, speed); };
    double p = 40.0, t = 0.0;
    const double h = 1e-4;
    for (int k = 0; k < 2000; ++k, t += h) {
      const double a = rate(t, p), b = rate(t + h / 2, p + h / 2 * a), c = rate(t + h / 2, p + h / 2 * b),
                   d = rate(t + h, p + h * c);
      p += h / 6 * (a + 2 * b + 2 * c + d);
    }
    const double x1 = x0 + speed * t;
    const double expected = law.absolute(40.0) * std::pow(law.volume(x0) / law.volume(x1), law.n);
    EXPECT_NEAR(law.absolute(p), expected, 1e-8 * expected) << speed;
    EXPECT_GT(std::fabs(law.absolute(p) - law.absolute(40.0)), 10.0) << speed;  // it moved a lot
    EXPECT_EQ(law.absolute(p) < law.absolute(40.0), speed > 0) << speed;       // contracting lowers it
  }
  // A closed valve passes nothing; an open one fills choked at `rate` (v = 1) and stops at the supply.
  EXPECT_EQ(air.flow(30.0, 0.0), 0.0);
  EXPECT_NEAR(air.pressureRate(100.0, -10.0, 0.0, 0.0), 1.25 * 400.0, 1e-9);
  EXPECT_NEAR(air.flow(90.0, 1.0), 0.0, 1e-12);  // p = supply - w
  EXPECT_NEAR(PneumaticAir::psi(0.1), PneumaticAir::psi(0.5282817877171743), 1e-15);
  EXPECT_NEAR(PneumaticAir::psi(0.8), std::sqrt(7.0 * (std::pow(0.8, 1 / 0.7) - std::pow(0.8, 1.2 / 0.7))), 1e-15);
}

TEST(OraclePneumatic, IntegrationConverges) {
  // Over a wide range, filling and venting, with friction and both stops met: 1e-11 against 1e-13, and
  // steps of at most 10 us.
  const auto u =
      makeSignal("steps:lo=-3.5,hi=4,min=0.3,max=1.5,dur=5+multisine:fmin=0.1,fmax=4,n=15,lo=-3.5,hi=4", 10.0, Ts, 5);
  const std::vector<EffectSpec> e = {parseEffect(
      "pneumatic_balance:fn=7,zeta=0.4,w=20,L=80,f0=0.1,fp=0.01,k_slip=3,spread=8,lo=2,hi=26,rate=600,vent=0.7,"
      "band=2,span=15,supply=110,swell=0.02,n=1.3")};
  const double noise = std::sqrt(0.005 * 0.005 + 0.001 * 0.001 / 12.0);
  const auto base = yClean(Core{}, e, u);
  SimOptions fine = clean();
  fine.rtol = fine.atol = 1e-13;
  SimOptions tiny = clean();
  tiny.max_step = 1e-5;
  const double d_fine = maxAbsDiff(base, yClean(Core{}, e, u, fine)), d_tiny = maxAbsDiff(base, yClean(Core{}, e, u, tiny));
  std::printf("pneumatic_balance: 1e-13 moves it by %.2g mm, 10 us steps by %.2g mm\n", d_fine, d_tiny);
  EXPECT_LT(d_fine, 1e-3 * noise);
  EXPECT_LT(d_tiny, 1e-3 * noise);
  EXPECT_GT(std::count_if(base.begin(), base.end(), [](double v) { return v == 2.0; }), 50);
  EXPECT_GT(std::count_if(base.begin(), base.end(), [](double v) { return v == 26.0; }), 50);
}

TEST(OraclePneumatic, IsAnAlternativeOfTheOtherPayloads) {
  EXPECT_THROW(validateEffects({parseEffect("pneumatic_balance"), parseEffect("muscle_balance")}),
               std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("pneumatic_balance"), parseEffect("mass_spring")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("pneumatic_balance:lo=3,hi=2")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("pneumatic_balance:rate=1")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("pneumatic_balance:n=1.5")}), std::invalid_argument);
  Stepper st(linearCore(), {balance("")}, clean());
  EXPECT_TRUE(std::isnan(st.pressure()));
}

// ---- the core ---------------------------------------------------------------------------------

TEST(OracleCore, SlowRampFollowsTheBoucWenClosedForm) {
  for (double alpha : {1.0, 1.3}) {
    for (double sign : {1.0, -1.0}) {
      Core c;  // k 6.5, rho 1.15, b 20, beta 0.5, gamma 0.2
      c.alpha = alpha;
      const auto u = ramp(0.0, 3.0 * sign, 30000);  // 0.1 V/s from rest at h = 0
      const auto y = yClean(c, {}, u);
      const double cc = c.beta + c.gamma;
      double worst = 0.0;
      for (size_t k = 0; k < u.size(); ++k) {
        const double v = u[k];
        // Loading from h = 0: dh/dv = alpha - c h for v > 0 (h > 0), alpha + c h for v < 0 (h < 0).
        const double h = sign * (alpha / cc) * (1.0 - std::exp(-cc * std::fabs(v)));
        const double expect = c.k * c.rho * v + c.b + c.k * (1.0 - c.rho) * h;
        worst = std::max(worst, std::fabs(y[k] - expect));
      }
      EXPECT_LT(worst, 1e-6) << "alpha " << alpha << " sign " << sign;
    }
  }
}

TEST(OracleCore, OutputRespondsToTheCommandOfTheSameSample) {
  const auto u = step(500, 0.0, 500, 1.0);
  const auto y = yClean(Core{}, {}, u);
  EXPECT_LT(std::fabs(y[499] - y[0]), 1e-9);
  EXPECT_GT(std::fabs(y[500] - y[499]), 5.0);  // the step is complete at the end of its own sample
}

// ---- stepped, as the plant of a closed loop ----------------------------------------------------

// A proportional loop on the stepper: each command is computed from the last measurement, which a batch
// run cannot do. The loop settles where the core's gain puts it, and a reset replays the run exactly.
TEST(OracleStepper, AProportionalLoopSettlesAndAResetReplaysIt) {
  SimOptions o;  // noise and quantisation on: the replay must restart the noise too
  Stepper st(Core{}, {parseEffect("pressure_lag:tau=0.02"), parseEffect("delay:d=0.0025")}, o);
  auto run = [&] {
    st.reset(0.0);
    std::vector<double> y;
    double u = 0.0, yk = Core{}.b;
    for (int k = 0; k < 3000; ++k) {
      u = std::clamp(u + 0.02 * (25.0 - yk), -5.0, 5.0);  // integral action on the setpoint 25 mm
      yk = st.step(u);
      y.push_back(yk);
    }
    return y;
  };
  const auto a = run(), b = run();
  EXPECT_EQ(a, b);
  EXPECT_NEAR(st.clean(), 25.0, 0.05);  // the integral drives the error to the noise
}

// A sample's measurement depends on no later command: with a delay of 2.5 samples a command changed at
// sample j first shows at the end of sample j + 2.
TEST(OracleStepper, ACommandActsAfterTheDelayAndNotBefore) {
  Stepper a(Core{}, {parseEffect("delay:d=0.0025")}, clean()), b(Core{}, {parseEffect("delay:d=0.0025")}, clean());
  a.reset(0.5);
  b.reset(0.5);
  const int j = 100;
  for (int k = 0; k < j + 5; ++k) {
    const double ya = a.step(0.5), yb = b.step(k >= j ? 1.5 : 0.5);
    if (k <= j + 1)
      EXPECT_EQ(ya, yb) << k;
    else
      EXPECT_GT(yb - ya, 1.0) << k;
  }
  EXPECT_THROW(a.step(NAN), std::invalid_argument);
}

// ---- the effects ------------------------------------------------------------------------------

TEST(OracleEffects, DelayShiftsTheStepResponseByDelayWithinASample) {
  const size_t ks = 1000;
  const auto u = step(ks, 0.0, 1000, 1.0);
  for (double d : {0.0, 0.02, 0.0234, 0.0577}) {
    std::vector<EffectSpec> e;
    if (d > 0) e.push_back(parseEffect("delay:d=" + std::to_string(d)));
    const auto y = yClean(Core{}, e, u);
    size_t on = 0;
    while (on < y.size() && std::fabs(y[on] - y[0]) < 1e-3) ++on;
    ASSERT_LT(on, y.size());
    // The delayed command switches at ks Ts + d; the first sample whose end is after it responds.
    const double t_end = static_cast<double>(on + 1) * Ts, t_switch = static_cast<double>(ks) * Ts + d;
    EXPECT_GE(t_end, t_switch - 1e-12) << d;
    EXPECT_LE(t_end - t_switch, Ts + 1e-12) << d;
  }
}

TEST(OracleEffects, PressureLagReaches63PercentAfterTau) {
  const size_t ks = 500;
  const auto u = step(ks, 0.0, 2000, 0.1);  // small: 1.25 V/s, far below the slew limit
  for (double tau : {0.02, 0.08, 0.3}) {
    const auto y = yClean(linearCore(), {parseEffect("pressure_lag:tau=" + std::to_string(tau) + ",slew=1000")}, u);
    const double y0 = y[ks - 1], y1 = linearCore().k * 0.1 + linearCore().b;
    const double t63 = crossingTime(y, ks - 1, y0 + (1.0 - std::exp(-1.0)) * (y1 - y0));
    EXPECT_NEAR(t63, tau, 0.05 * tau) << tau;
  }
}

TEST(OracleEffects, PressureLagSlewLimitsTheRate) {
  const size_t ks = 500;
  const auto u = step(ks, -1.0, 1000, 1.0);
  const auto y = yClean(linearCore(), {parseEffect("pressure_lag:tau=0.002,slew=20")}, u);
  // Mid-rise the pressure moves at the slew rate: dy/dt = k slew.
  const double rate = (y[ks + 60] - y[ks + 40]) / (20 * Ts);
  EXPECT_NEAR(rate, linearCore().k * 20.0, 0.02 * linearCore().k * 20.0);
}

TEST(OracleEffects, MassSpringRingsAtFn) {
  const size_t ks = 500;
  const auto u = step(ks, 0.0, 3000, 0.5);
  for (double fn : {2.0, 6.0, 15.0}) {
    const double zeta = 0.05;
    const auto y = yClean(linearCore(), {parseEffect("mass_spring:fn=" + std::to_string(fn) + ",zeta=0.05")}, u);
    const double yf = linearCore().k * 0.5 + linearCore().b;
    std::vector<double> up;  // upward crossings of the final value
    for (size_t k = ks; k + 1 < y.size(); ++k)
      if (y[k] < yf && y[k + 1] >= yf) up.push_back(static_cast<double>(k) + (yf - y[k]) / (y[k + 1] - y[k]));
    ASSERT_GE(up.size(), 4u) << fn;
    const double period = (up[3] - up[0]) / 3.0 * Ts;
    const double fn_est = 1.0 / period / std::sqrt(1.0 - zeta * zeta);
    EXPECT_NEAR(fn_est, fn, 0.05 * fn);
    // The first overshoot: exp(-pi zeta / sqrt(1 - zeta^2)).
    const double peak = *std::max_element(y.begin() + ks, y.end());
    EXPECT_NEAR((peak - yf) / (yf - y[0]), std::exp(-M_PI * zeta / std::sqrt(1 - zeta * zeta)), 0.03);
  }
}

TEST(OracleEffects, CreepDriftsByFractionWithTau) {
  const size_t ks = 1000;
  const double tau = 2.0, fraction = 0.1;
  const auto u = step(ks, 0.0, 16000, 1.0);
  const auto y = yClean(linearCore(), {parseEffect("creep:fraction=0.1,tau=2")}, u);
  const double k = linearCore().k;
  // At rest at u = 0 the creep already holds fraction x b; the step adds k du now and fraction k du later.
  EXPECT_NEAR(y[ks] - y[ks - 1], k * 1.0, 0.01);
  EXPECT_NEAR(y.back() - y[ks - 1], (1.0 + fraction) * k, 0.01 * fraction * k);
  const double t63 = crossingTime(y, ks - 1, y[ks - 1] + k + (1.0 - std::exp(-1.0)) * fraction * k);
  EXPECT_NEAR(t63, tau, 0.05 * tau);
}

TEST(OracleEffects, DeadBandFreezesTheOutputBelowTheThreshold) {
  std::vector<double> u(20000);
  for (size_t i = 0; i < u.size(); ++i) u[i] = 3.0 * std::sin(2.0 * M_PI * 0.1 * static_cast<double>(i) * Ts);
  const auto y = yClean(Core{}, {parseEffect("dead_band:threshold=-1")}, u);
  const auto y_plain = yClean(Core{}, {}, u);
  int intervals = 0;
  for (size_t i = 0; i < u.size();) {
    if (!(u[i] < -1.0 - 1e-6)) {
      ++i;
      continue;
    }
    // One interval below the threshold (the level of each depends on the hysteresis state on entry).
    double lo = 1e9, hi = -1e9, lo_p = 1e9, hi_p = -1e9;
    for (; i < u.size() && u[i] < -1.0 - 1e-6; ++i) {
      lo = std::min(lo, y[i]), hi = std::max(hi, y[i]);
      lo_p = std::min(lo_p, y_plain[i]), hi_p = std::max(hi_p, y_plain[i]);
    }
    ++intervals;
    EXPECT_LT(hi - lo, 1e-9);     // frozen below the threshold
    EXPECT_GT(hi_p - lo_p, 5.0);  // ... where the plain muscle moves
  }
  EXPECT_EQ(intervals, 2);
  // Above it the command passes: somewhere the two agree (the first rise, before the threshold is met).
  EXPECT_LT(std::fabs(y[1000] - y_plain[1000]), 1e-9);
}

TEST(OracleEffects, SaturationFlattensAboveTheKnee) {
  const auto u = ramp(-3.0, 3.0, 20000);
  const auto y = yClean(linearCore(), {parseEffect("saturation:knee=30,width=5")}, u);
  double worst = 0.0;
  for (size_t k = 0; k < u.size(); ++k) {
    const double yc = 6.5 * u[k] + 20.0;
    const double expect = yc <= 30.0 ? yc : 30.0 + 5.0 * std::tanh((yc - 30.0) / 5.0);
    worst = std::max(worst, std::fabs(y[k] - expect));
  }
  EXPECT_LT(worst, 1e-6);
  EXPECT_LT(*std::max_element(y.begin(), y.end()), 35.0);
}

TEST(OracleEffects, AsymmetryTurnsRoundOverDifferentTravels) {
  const double gain = 2.0, wu = 1.0, wd = 0.3;
  std::vector<double> u = ramp(0.0, 3.0, 6000), down = ramp(3.0, -3.0, 12000), up = ramp(-3.0, 3.0, 12000);
  u.insert(u.end(), down.begin() + 1, down.end());
  u.insert(u.end(), up.begin() + 1, up.end());
  const auto y = yClean(linearCore(), {parseEffect("asymmetry:gain=2,w_up=1,w_down=0.3")}, u);
  // The closed form of dz/du = 1 - z / w_up rising, 1 + z / w_down falling, along the path.
  double z = 0.0, worst = 0.0;
  for (size_t k = 0; k < u.size(); ++k) {
    const double du = k ? u[k] - u[k - 1] : 0.0;
    if (du > 0) z = wu - (wu - z) * std::exp(-du / wu);
    if (du < 0) z = -wd + (z + wd) * std::exp(du / wd);
    worst = std::max(worst, std::fabs(y[k] - (6.5 * u[k] + 20.0 + gain * z)));
  }
  EXPECT_LT(worst, 1e-6);
  auto zOf = [&](size_t k) { return (y[k] - (6.5 * u[k] + 20.0)) / gain; };
  // The branches at u = 0: falling, z has turned round over w_down and sits near -w_down after 3 V of
  // travel; rising from -3 V it has come only to about w_up - (w_up + w_down) exp(-3 / w_up).
  auto zAtZero = [&](size_t from, size_t to) {  // z where u crosses 0 between the two indices
    for (size_t k = from; k + 1 < to; ++k)
      if ((u[k] <= 0.0) != (u[k + 1] <= 0.0)) return zOf(k) + (zOf(k + 1) - zOf(k)) * u[k] / (u[k] - u[k + 1]);
    return 1e9;
  };
  const size_t top = 5999, bottom = 6000 + 12000 - 2;
  const double z_top = wu * (1.0 - std::exp(-3.0 / wu)), z_bottom = -wd + (z_top + wd) * std::exp(-6.0 / wd);
  EXPECT_NEAR(zAtZero(top, bottom), -wd + (z_top + wd) * std::exp(-3.0 / wd), 1e-6);
  EXPECT_NEAR(zAtZero(bottom, u.size()), wu - (wu - z_bottom) * std::exp(-3.0 / wu), 1e-6);
  // Turning round: half of the swing takes w_down ln 2 of command travel after the top reversal and
  // w_up ln 2 after the bottom one.
  auto halfTravel = [&](size_t rev, double target) {
    const double half = 0.5 * (zOf(rev) + target);
    for (size_t k = rev; k + 1 < u.size(); ++k)
      if ((zOf(k) - half) * (zOf(k + 1) - half) <= 0.0) return std::fabs(u[k + 1] - u[rev]);
    return 1e9;
  };
  EXPECT_NEAR(halfTravel(top, -wd), wd * std::log(2.0), 0.05 * wd * std::log(2.0));
  EXPECT_NEAR(halfTravel(bottom, wu), wu * std::log(2.0), 0.05 * wu * std::log(2.0));
}

TEST(OracleEffects, FrictionSticksAfterEveryReversal) {
  const double zmax = 0.5;
  std::vector<double> u = ramp(0.0, 3.0, 6000), down = ramp(3.0, -3.0, 12000);
  u.insert(u.end(), down.begin() + 1, down.end());
  const auto y = yClean(linearCore(), {parseEffect("friction_hysteresis:zmax=0.5,delta=0.1")}, u);
  const auto y0 = yClean(linearCore(), {}, u);
  // Rising (friction saturated at +zmax) the output runs zmax below the frictionless one, falling zmax above.
  EXPECT_NEAR(y0[5000] - y[5000], zmax, 0.01 * zmax);
  EXPECT_NEAR(y[6000 + 9000] - y0[6000 + 9000], zmax, 0.01 * zmax);
  // Before the reversal the output follows the command at the full slope k; right after it, it sticks:
  // dy/du = k / (1 + a g) with a = zmax / delta = 5, g = 2.
  const double du = 3.0 / 5999.0;
  const double slope_before = (y[5999] - y[5989]) / (10 * du);
  const double slope_after = (y[6000] - y[6010]) / (10 * du);
  EXPECT_NEAR(slope_before, 6.5, 0.02 * 6.5);
  EXPECT_NEAR(slope_after, 6.5 / (1.0 + 5.0 * 2.0), 0.1 * 6.5 / 11.0);
}

TEST(OracleEffects, ForceLoopWithoutFrictionIsMassSpringAndWithItHoldsShort) {
  const size_t ks = 500;
  const auto u = step(ks, 0.0, 4000, 0.5);
  const auto ms = yClean(linearCore(), {parseEffect("mass_spring:fn=6,zeta=0.1")}, u);
  const auto fl0 = yClean(linearCore(), {parseEffect("force_loop:fn=6,zeta=0.1,zmax=0")}, u);
  EXPECT_LT(maxAbsDiff(ms, fl0), 1e-7);
  const auto fl = yClean(linearCore(), {parseEffect("force_loop:fn=6,zeta=0.1,zmax=0.4,delta=0.05")}, u);
  const double yf = 6.5 * 0.5 + 20.0;
  const double offset = yf - fl.back();
  EXPECT_GT(std::fabs(offset), 1e-3);                           // stuck short of the static position
  EXPECT_LE(std::fabs(offset), 0.4 + 1e-6);                     // by at most the Coulomb level
  EXPECT_LT(std::fabs(fl.back() - fl[fl.size() - 500]), 1e-4);  // and at rest
  // Friction takes energy out: the first overshoot is smaller than without it.
  EXPECT_LT(*std::max_element(fl.begin(), fl.end()) - yf, *std::max_element(ms.begin(), ms.end()) - yf - 0.1);
}

TEST(OracleEffects, LoadMovesTheOutputByComplianceTimesLoad) {
  const auto u = std::vector<double>(2000, 0.5);
  const auto load = step(1000, 0.0, 1000, 40.0);
  const auto y = yClean(Core{}, {parseEffect("load:compliance=0.05")}, u, clean(), &load);
  EXPECT_NEAR(y[999] - y[1000], 0.05 * 40.0, 1e-6);
  EXPECT_NEAR(y[0], y[999], 1e-9);
  EXPECT_THROW(yClean(Core{}, {parseEffect("load")}, u), std::invalid_argument);  // no load column
}

TEST(OracleEffects, WarmUpShiftsAndScalesWithTheThermalTimeConstant) {
  const size_t ks = 5000;
  const auto u = step(ks, 0.0, 5000, 1.0);
  const auto y = yClean(linearCore(), {parseEffect("warm_up:tau=5,gain=0.1,shift=1")}, u);
  double worst = 0.0;
  for (size_t k = 0; k < u.size(); ++k) {
    const double phi = 1.0 - std::exp(-static_cast<double>(k + 1) * Ts / 5.0);
    const double yc = 6.5 * u[k] + 20.0;
    worst = std::max(worst, std::fabs(y[k] - (yc + phi * (0.1 * (yc - 20.0) + 1.0))));
  }
  EXPECT_LT(worst, 1e-6);
}

// ---- noise ------------------------------------------------------------------------------------

TEST(OracleNoise, StdAtAHoldMatchesTheConfiguredOne) {
  const std::vector<double> u(20000, 1.0);
  for (double sd : {0.005, 0.0005, 0.02}) {
    SimOptions o;
    o.noise_std = sd;
    o.noise_seed = 42;
    const Record r = simulate(Core{}, {}, u, nullptr, o);
    const double mean = std::accumulate(r.y.begin(), r.y.end(), 0.0) / static_cast<double>(r.y.size());
    double ss = 0.0;
    for (double v : r.y) ss += (v - mean) * (v - mean);
    const double measured = std::sqrt(ss / static_cast<double>(r.y.size() - 1));
    const double expected = std::sqrt(sd * sd + 0.001 * 0.001 / 12.0);
    EXPECT_NEAR(r.noise(), expected, 1e-12);
    EXPECT_NEAR(measured, expected, 0.1 * expected) << sd;
    EXPECT_NEAR(mean, r.y_clean[0], 4.0 * expected / std::sqrt(static_cast<double>(u.size())) + 0.0005);
    // Quantised to 0.001 mm.
    for (size_t i = 0; i < 100; ++i) EXPECT_NEAR(r.y[i] * 1000.0, std::round(r.y[i] * 1000.0), 1e-6);
  }
}

// ---- excitations, records, cases --------------------------------------------------------------

TEST(OracleSignals, KindsStayInRangeAreSeededAndRejectBadSpecs) {
  for (const char* spec : {"steps", "chirp:f1=5", "sine:f=0.1", "triangle", "multisine:fmax=3", "hold:level=1",
                           "ramp:from=-3,to=3", "mixed", "steps:dur=5+chirp:f1=3+hold"}) {
    const auto u = makeSignal(spec, 20.0, Ts, 3);
    ASSERT_EQ(u.size(), 20000u) << spec;
    for (double v : u) ASSERT_TRUE(v >= -3.0 - 1e-12 && v <= 3.0 + 1e-12) << spec;
    EXPECT_EQ(u, makeSignal(spec, 20.0, Ts, 3)) << spec;
  }
  EXPECT_NE(makeSignal("steps", 20.0, Ts, 3), makeSignal("steps", 20.0, Ts, 4));
  for (const char* bad : {"", "bogus", "steps:lo", "steps:foo=1", "sine:f=-1", "steps:dur=30", "chirp:f1=abc"})
    EXPECT_THROW(makeSignal(bad, 20.0, Ts, 1), std::invalid_argument) << bad;
  EXPECT_THROW(parseEffect("delay:dd=1"), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("delay:d=0.3")}), std::invalid_argument);
  EXPECT_THROW(validateEffects({parseEffect("mass_spring"), parseEffect("force_loop")}), std::invalid_argument);
  EXPECT_THROW(parseCore("k=1,q=2"), std::invalid_argument);
}

TEST(OracleRecords, CsvIsWrittenAtomicallyAndReadsBack) {
  const std::vector<double> u = makeSignal("steps", 2.0, Ts, 1), load(u.size(), 3.0);
  const Record r = simulate(Core{}, {parseEffect("load")}, u, &load, SimOptions{});
  const std::string path = ::testing::TempDir() + "oracle_record.csv";
  writeRecordCsv(path, r);
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "t,u,y,load");
  size_t rows = 0;
  double t_prev = -1.0;
  while (std::getline(in, line)) {
    double t, uu, y, l;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &t, &uu, &y, &l), 4);
    if (rows) {
      EXPECT_NEAR(t - t_prev, Ts, 1e-9);
    }
    EXPECT_NEAR(y, r.y[rows], 1e-6);
    t_prev = t;
    ++rows;
  }
  EXPECT_EQ(rows, u.size());
  EXPECT_FALSE(std::ifstream(path + ".tmp").good());
  std::remove(path.c_str());
  EXPECT_THROW(writeRecordCsv("/nonexistent-dir/x.csv", r), std::runtime_error);
}

TEST(OracleCases, ThePreDecidedSetIsWellFormed) {
  const auto cases = loadCases(defaultCasesPath());
  std::set<std::string> single;
  bool plain = false;
  int pairs = 0;
  for (const auto& c : cases) {
    std::vector<std::string> hidden;
    for (const auto& e : c.effects) hidden.push_back(e.name);
    std::sort(hidden.begin(), hidden.end());
    auto expected = c.expected;
    std::sort(expected.begin(), expected.end());
    EXPECT_EQ(hidden, expected) << c.name;
    EXPECT_NO_THROW(validateEffects(c.effects)) << c.name;
    EXPECT_TRUE(c.train.duration >= 30 && c.train.duration <= 60) << c.name;
    EXPECT_TRUE(c.validate.duration >= 20 && c.validate.duration <= 30) << c.name;
    EXPECT_NE(c.train.seed, c.validate.seed) << c.name;
    EXPECT_NE(c.train.input, c.validate.input) << c.name;
    EXPECT_NO_THROW(makeSignal(c.train.input, c.train.duration, Ts, c.train.seed)) << c.name;
    EXPECT_NO_THROW(makeSignal(c.validate.input, c.validate.duration, Ts, c.validate.seed)) << c.name;
    // Not the project's default core (k 5, rho 0.8, beta 0.3, gamma 0.3).
    EXPECT_FALSE(c.core.k == 5.0 && c.core.rho == 0.8) << c.name;
    const bool needs_load = std::count(expected.begin(), expected.end(), "load") > 0;
    EXPECT_EQ(needs_load, !c.train.load.empty()) << c.name;
    EXPECT_EQ(needs_load, !c.validate.load.empty()) << c.name;
    if (expected.empty()) plain = true;
    if (expected.size() == 1) single.insert(expected[0]);
    if (expected.size() == 2) ++pairs;
  }
  EXPECT_TRUE(plain);
  EXPECT_GE(pairs, 2);
  for (const char* e :
       {"pressure_lag", "creep", "mass_spring", "delay", "dead_band", "saturation", "asymmetry", "friction_hysteresis"})
    EXPECT_TRUE(single.count(e)) << e;
}

TEST(OracleCases, ARecordIsReproducibleAndTheTwoRecordsDiffer) {
  auto cases = loadCases(defaultCasesPath());
  ASSERT_FALSE(cases.empty());
  Case c = cases.front();
  c.train.duration = 3.0;
  c.validate.duration = 3.0;
  const Record a = makeCaseRecord(c, "train"), b = makeCaseRecord(c, "train"), v = makeCaseRecord(c, "validate");
  EXPECT_EQ(a.y, b.y);
  EXPECT_NE(a.u, v.u);
  EXPECT_NEAR(a.noise(), std::sqrt(c.noise_std * c.noise_std + 1e-6 / 12.0), 1e-12);
}

// The pre-decided whole-stroke case (wide_range.json, judged by tools/wide_range_judge.py): well-formed,
// over -3.5..4 V, its training record meets both end stops.
TEST(OracleCases, TheWideRangeCaseIsWellFormedAndMeetsBothStops) {
  const auto cases = loadCases(std::string(PAMC_ORACLE_SOURCE_DIR) + "/wide_range.json");
  ASSERT_EQ(cases.size(), 1u);
  const Case& c = cases[0];
  ASSERT_EQ(c.effects.size(), 1u);
  EXPECT_EQ(c.effects[0].name, "muscle_balance");
  EXPECT_EQ(c.expected, std::vector<std::string>{"muscle_balance"});
  EXPECT_NE(c.train.seed, c.validate.seed);
  EXPECT_NE(c.train.input, c.validate.input);
  EXPECT_TRUE(c.train.duration >= 30 && c.train.duration <= 60);
  const Record r = makeCaseRecord(c, "train");
  EXPECT_NEAR(*std::min_element(r.u.begin(), r.u.end()), -3.5, 0.2);
  EXPECT_NEAR(*std::max_element(r.u.begin(), r.u.end()), 4.0, 0.2);
  for (const char* stop : {"lo", "hi"}) {
    const double at = c.effects[0].params.at(stop);
    EXPECT_GT(std::count(r.y_clean.begin(), r.y_clean.end(), at), 20) << stop;
  }
}

TEST(OracleCases, ThePneumaticRangeCaseIsWellFormedAndMeetsBothStops) {
  const auto cases = loadCases(std::string(PAMC_ORACLE_SOURCE_DIR) + "/pneumatic_range.json");
  const auto wide = loadCases(std::string(PAMC_ORACLE_SOURCE_DIR) + "/wide_range.json");
  ASSERT_EQ(cases.size(), 1u);
  const Case& c = cases[0];
  ASSERT_EQ(c.effects.size(), 1u);
  EXPECT_EQ(c.effects[0].name, "pneumatic_balance");
  EXPECT_EQ(c.expected, std::vector<std::string>{"pneumatic_balance"});
  EXPECT_EQ(c.noise_std, 0.005);
  EXPECT_NE(c.train.seed, c.validate.seed);
  EXPECT_NE(c.train.input, c.validate.input);
  EXPECT_TRUE(c.train.duration >= 30 && c.train.duration <= 60);
  EXPECT_TRUE(c.validate.duration >= 20 && c.validate.duration <= 30);
  for (const Case& o : wide) {  // another case than wide_range.json's
    for (const RecordSpec* a : {&c.train, &c.validate})
      for (const RecordSpec* b : {&o.train, &o.validate}) {
        EXPECT_NE(a->seed, b->seed);
        EXPECT_NE(a->input, b->input);
      }
    for (const char* k : {"fn", "zeta", "w", "L", "f0", "fp", "k_slip", "spread", "lo", "hi"})
      EXPECT_NE(c.effects[0].params.at(k), o.effects[0].params.at(k)) << k;
  }
  // A plausible pressure: 1 bar = span, the supply 6-9 bar gauge.
  const auto& q = c.effects[0].params;
  EXPECT_GE(q.at("supply") / q.at("span"), 6.0);
  EXPECT_LE(q.at("supply") / q.at("span"), 9.0);
  const Record r = makeCaseRecord(c, "train");
  EXPECT_NEAR(*std::min_element(r.u.begin(), r.u.end()), -3.5, 0.2);
  EXPECT_NEAR(*std::max_element(r.u.begin(), r.u.end()), 4.0, 0.2);
  for (const char* stop : {"lo", "hi"}) {
    const double at = q.at(stop);
    EXPECT_GT(std::count(r.y_clean.begin(), r.y_clean.end(), at), 20) << stop;
  }
  // The valve fills the stroke (from the lower stop to the upper, -3.5 -> 4 V) in 50-200 ms and vents it slower.
  double took[2];
  for (int j = 0; j < 2; ++j) {
    Stepper st(c.core, c.effects, clean());
    st.reset(j == 0 ? -3.5 : 4.0);
    const double target = q.at(j == 0 ? "hi" : "lo");
    int k = 0;
    while (k < 2000 && st.step(j == 0 ? 4.0 : -3.5) != target) ++k;
    took[j] = (k + 1) * Ts;
  }
  std::printf("pneumatic_range: the stroke fills in %.3f s, vents in %.3f s\n", took[0], took[1]);
  EXPECT_GE(took[0], 0.05);
  EXPECT_LE(took[0], 0.2);
  EXPECT_GT(took[1], took[0]);
  const Record v = makeCaseRecord(c, "validate");
  for (const char* stop : {"lo", "hi"}) EXPECT_GT(std::count(v.y_clean.begin(), v.y_clean.end(), q.at(stop)), 0) << stop;
}

// The pre-committed set outside the catalogue (unseen.json): every case loads, names its kind, and its
// effect is visible - the record with it differs from the same record without it by well above the noise.
TEST(Unseen, EveryCaseIsAVisibleEffectOutsideTheCatalogue) {
  const std::string path = std::string(PAMC_ORACLE_SOURCE_DIR) + "/unseen.json";
  const auto cases = loadCases(path);
  ASSERT_GE(cases.size(), 8u);
  for (const auto& c : cases) {
    ASSERT_EQ(c.effects.size(), 1u) << c.name;
    EXPECT_NE(effectInfo(c.effects[0].name).meaning.find("outside the catalogue"), std::string::npos) << c.name;
    Case bare = c;
    bare.effects.clear();
    const auto with = makeCaseRecord(c, "train");
    const auto without = makeCaseRecord(bare, "train");
    double acc = 0;
    for (size_t k = 0; k < with.y_clean.size(); ++k) acc += std::pow(with.y_clean[k] - without.y_clean[k], 2);
    const double rms = std::sqrt(acc / static_cast<double>(with.y_clean.size()));
    std::printf("unseen %-22s effect rms %.4f mm (%.1fx the noise)\n", c.name.c_str(), rms, rms / with.noise());
    EXPECT_GT(rms, 5.0 * with.noise()) << c.name;
  }
}
