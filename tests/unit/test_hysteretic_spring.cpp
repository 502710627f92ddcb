// hysteretic_spring: the Bouc-Wen element with its |z| term inside the payload's force balance
// (m y'' + c y' + k y + z = F). Checked against an independent fine-step integration of the equation the
// public Bouc-Wen benchmark follows (here, in the test), its branches against its header, its bounds
// under hard inputs, that a model takes it or mass_spring / force_loop but not two of them, that diagnose
// does not try it as a candidate of its own, and that diagnose finds it in mass_spring's place on a
// record of such a system made by the test's own integration with other parameters and another
// excitation than the benchmark's.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "diagnose/diagnose.hpp"
#include "model/model.hpp"

using namespace pamc;

namespace {

// The system in SI units, m y'' + c y' + k y + z = u, z' = alpha y' - beta (gamma |y'| z - delta y' |z|)
// (delta > 0 stiffens: the benchmark's data follow delta = 1.1 in this sign).
struct System {
  double m = 2.0, c = 10.0, k = 5e4, alpha = 5e4, beta = 1e3, gamma = 0.8, delta = 1.1;
};

void derivative(const System& b, const double* x, double F, double* d) {
  d[0] = x[1];
  d[1] = (F - b.c * x[1] - b.k * x[0] - x[2]) / b.m;
  d[2] = b.alpha * x[1] - b.beta * (b.gamma * std::fabs(x[1]) * x[2] - b.delta * x[1] * std::fabs(x[2]));
}

// The force at the fraction t of the interval ending at sample n: on the ramp from u_{n-1} (order 1) or
// on the parabola through u_{n-2}, u_{n-1}, u_n (order 2).
double forceAt(const std::vector<double>& u, size_t n, int order, double t) {
  const double uk = u[n], uk1 = n >= 1 ? u[n - 1] : 0.0, uk2 = n >= 2 ? u[n - 2] : 0.0;
  if (order == 1) return uk1 + t * (uk - uk1);
  return uk1 + 0.5 * t * (uk - uk2) + 0.5 * t * t * (uk - 2.0 * uk1 + uk2);
}

// Classical Runge-Kutta with `sub` steps per sample from rest; y in mm at the samples.
std::vector<double> integrate(const System& b, const std::vector<double>& u, double Ts, int order, int sub) {
  std::vector<double> y(u.size());
  double x[3] = {0, 0, 0};
  const double h = Ts / sub;
  for (size_t n = 0; n < u.size(); ++n) {
    for (int i = 0; i < sub; ++i) {
      const double t0 = static_cast<double>(i) / sub, tm = (i + 0.5) / sub, t1 = static_cast<double>(i + 1) / sub;
      double k1[3], k2[3], k3[3], k4[3], xt[3];
      derivative(b, x, forceAt(u, n, order, t0), k1);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + 0.5 * h * k1[j];
      derivative(b, xt, forceAt(u, n, order, tm), k2);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + 0.5 * h * k2[j];
      derivative(b, xt, forceAt(u, n, order, tm), k3);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + h * k3[j];
      derivative(b, xt, forceAt(u, n, order, t1), k4);
      for (int j = 0; j < 3; ++j) x[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    }
    y[n] = 1e3 * x[0];
  }
  return y;
}

// The same system as a linear core (y_core = u / k, in mm) + hysteretic_spring, by the effect's header:
// fn = sqrt(k / m) / 2 pi, zeta = c / (2 sqrt(k m)), delta = 1 / (beta gamma), zmax = alpha / k delta,
// hardening = delta_bw / gamma (lengths in mm).
model::Model modelOf(const System& b, double hold_order) {
  model::Model m({1e3 / b.k, 1.0, 0.0, 1.0, 0.3, 0.3});
  m.addEffect("hysteretic_spring");
  const double travel = 1e3 / (b.beta * b.gamma);
  m.setEffectParam("hysteretic_spring", "fn", std::sqrt(b.k / b.m) / (2 * M_PI));
  m.setEffectParam("hysteretic_spring", "zeta", b.c / (2.0 * std::sqrt(b.k * b.m)));
  m.setEffectParam("hysteretic_spring", "delta", travel);
  m.setEffectParam("hysteretic_spring", "zmax", b.alpha / b.k * travel);
  m.setEffectParam("hysteretic_spring", "hardening", b.delta / b.gamma);
  m.setEffectParam("hysteretic_spring", "hold_order", hold_order);
  return m;
}

// A random-phase multisine over [f_lo, f_hi] Hz with the given force rms over n samples, as a function of
// continuous time.
class Multisine {
 public:
  Multisine(size_t n, double Ts, unsigned seed, double f_lo, double f_hi, double force_rms) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> phase(0.0, 2 * M_PI);
    const double T = static_cast<double>(n) * Ts;
    for (int l = 1; l / T <= f_hi; ++l)
      if (l / T >= f_lo) lines_.push_back({l / T, phase(rng)});
    double ss = 0.0;
    for (size_t k = 0; k < n; ++k) ss += std::pow((*this)(static_cast<double>(k) * Ts), 2);
    gain_ = force_rms / std::sqrt(ss / static_cast<double>(n));
  }
  double operator()(double t) const {
    double v = 0.0;
    for (const auto& [f, ph] : lines_) v += std::cos(2 * M_PI * f * t + ph);
    return gain_ * v;
  }

 private:
  std::vector<std::pair<double, double>> lines_;
  double gain_ = 1.0;
};

// Its samples after one sample at rest under no force: u_{k+1} = f(k Ts).
std::vector<double> multisine(size_t n, double Ts, unsigned seed, double f_lo, double f_hi, double force_rms) {
  const Multisine f(n, Ts, seed, f_lo, f_hi, force_rms);
  std::vector<double> u(n + 1, 0.0);
  for (size_t k = 0; k < n; ++k) u[k + 1] = f(static_cast<double>(k) * Ts);
  return u;
}

// Classical Runge-Kutta with `sub` steps per sample under the continuous force (the first interval, from
// rest to f(0), on a ramp); y in mm at the samples u_{k+1} = f(k Ts).
std::vector<double> integrateContinuous(const System& b, const Multisine& f, size_t n, double Ts, int sub) {
  std::vector<double> y(n + 1, 0.0);
  double x[3] = {0, 0, 0};
  const double h = Ts / sub;
  auto force = [&](size_t k, double t) { return k == 1 ? t * f(0.0) : f((static_cast<double>(k) - 2.0 + t) * Ts); };
  for (size_t k = 1; k <= n; ++k) {
    for (int i = 0; i < sub; ++i) {
      const double t0 = static_cast<double>(i) / sub, tm = (i + 0.5) / sub, t1 = static_cast<double>(i + 1) / sub;
      double k1[3], k2[3], k3[3], k4[3], xt[3];
      derivative(b, x, force(k, t0), k1);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + 0.5 * h * k1[j];
      derivative(b, xt, force(k, tm), k2);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + 0.5 * h * k2[j];
      derivative(b, xt, force(k, tm), k3);
      for (int j = 0; j < 3; ++j) xt[j] = x[j] + h * k3[j];
      derivative(b, xt, force(k, t1), k4);
      for (int j = 0; j < 3; ++j) x[j] += h / 6.0 * (k1[j] + 2 * k2[j] + 2 * k3[j] + k4[j]);
    }
    y[k] = 1e3 * x[0];
  }
  return y;
}

double rms(const std::vector<double>& a) {
  double s = 0.0;
  for (double v : a) s += v * v;
  return std::sqrt(s / static_cast<double>(a.size()));
}

double rmsDiff(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> e(a.size());
  for (size_t k = 0; k < a.size(); ++k) e[k] = a[k] - b[k];
  return rms(e);
}

io::Measurement recordOf(const std::vector<double>& u, const std::vector<double>& y, double Ts,
                         const std::string& name) {
  io::Measurement m;
  m.source = name;
  m.Ts = Ts;
  m.u = u;
  m.y = y;
  for (size_t k = 0; k < u.size(); ++k) m.t.push_back(static_cast<double>(k) * Ts);
  return m;
}

}  // namespace

// The benchmark's equation at its 750 Hz (ringing near 25-40 Hz): the sub-stepped integration within
// 1e-3 of the output's rms of a Runge-Kutta integration 400 times finer, for a stiffening, a saturating
// and a plain element, the force on a ramp and on a parabola within the sample; without the |z| term the
// benchmark's system is another one.
TEST(HystereticSpring, FollowsTheBoucWenBenchmarksEquation) {
  const double Ts = 1.0 / 750.0;
  const auto u = multisine(6000, Ts, 3, 5.0, 150.0, 50.0);
  for (double delta_bw : {1.1, -0.5, 0.0})
    for (int order : {1, 2}) {
      System b;
      b.delta = delta_bw;
      const auto ref = integrate(b, u, Ts, order, 400);
      const auto y = modelOf(b, order).simulate(u, Ts);
      std::printf("delta %.1f, hold order %d: y rms %.4f mm, model - reference rms %.2e mm\n", delta_bw, order,
                  rms(ref), rmsDiff(y, ref));
      EXPECT_LT(rmsDiff(y, ref), 1e-3 * rms(ref)) << delta_bw << " " << order;
    }
  System b;
  const auto ref = integrate(b, u, Ts, 2, 400);
  model::Model m = modelOf(b, 2);
  m.setEffectParam("hysteretic_spring", "hardening", 0.0);
  EXPECT_GT(rmsDiff(m.simulate(u, Ts), ref), 0.2 * rms(ref));
}

// The force within a sample, on a record like the benchmark's (its parameters, 750 Hz, a multisine to
// 150 Hz integrated under the continuous force): what the true parameters miss by with the force held
// over each sample, on a ramp, and on the parabola through the last three samples (docs/MODELING.md
// quotes the figures this prints). Each order closer than the one before.
TEST(HystereticSpring, TheForceWithinASampleMatters) {
  const double Ts = 1.0 / 750.0;
  const size_t n = 1500;
  const Multisine f(n, Ts, 5, 5.0, 150.0, 50.0);
  const auto u = multisine(n, Ts, 5, 5.0, 150.0, 50.0);
  const System b;
  const auto ref = integrateContinuous(b, f, n, Ts, 40);
  double last = 1e9;
  for (int order : {0, 1, 2}) {
    const double e = rmsDiff(modelOf(b, order).simulate(u, Ts), ref);
    std::printf(
        "the benchmark's system, true parameters, hold_order %d: misses the continuous-force record by %.4f mm "
        "(y rms %.3f mm)\n",
        order, e, rms(ref));
    EXPECT_LT(e, last) << order;
    last = e;
  }
}

// The element's slope is the header's: A = zmax / delta right after a reversal whatever the hardening,
// then A (1 - (1 - hardening) |z| / zmax) while |z| grows (a straight line for hardening 1).
TEST(HystereticSpring, HardeningBendsTheBranchesNotTheReversalSlope) {
  const double Ts = 1e-3;
  for (double h : {0.0, 0.5, 1.0, 1.5}) {
    // Quasi-static: a slow force sweep on a stiff, well-damped payload, so z = in - y.
    model::Model m({1.0, 1.0, 0.0, 1.0, 0.3, 0.3});
    m.addEffect("hysteretic_spring");
    for (const auto& [p, v] : std::vector<std::pair<std::string, double>>{
             {"fn", 40.0}, {"zeta", 0.9}, {"zmax", 1.0}, {"delta", 0.5}, {"hardening", h}, {"hold_order", 1.0}})
      m.setEffectParam("hysteretic_spring", p, v);
    const int n = 5000;  // the first quarter period of 0.05 Hz: loading from rest
    std::vector<double> u(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) u[static_cast<size_t>(k)] = 2.0 * std::sin(2 * M_PI * 0.05 * k * Ts);
    const auto y = m.simulate(u, Ts);
    for (size_t k : {60u, 1000u, 2500u, 4500u}) {
      const double slope = ((u[k + 20] - y[k + 20]) - (u[k - 20] - y[k - 20])) / (y[k + 20] - y[k - 20]);
      const double z = u[k] - y[k];
      const double expect = 2.0 * (1.0 - (1.0 - h) * std::fabs(z) / 1.0);
      EXPECT_NEAR(slope, expect, 0.02 * 2.0) << "hardening " << h << " at z = " << z;
    }
  }
}

TEST(HystereticSpring, StaysFiniteUnderHardInputs) {
  for (double fn : {0.2, 10.0, 100.0})
    for (double delta : {0.01, 0.5, 16.0})
      for (double h : {0.0, 1.0, 2.0})
        for (double order : {0.0, 0.5, 2.0}) {
          model::Model m({1.0, 1.0, 0.0, 1.0, 0.3, 0.3});
          m.addEffect("hysteretic_spring");
          m.setEffectParam("hysteretic_spring", "fn", fn);
          m.setEffectParam("hysteretic_spring", "zeta", 0.01);
          m.setEffectParam("hysteretic_spring", "zmax", 10.0);
          m.setEffectParam("hysteretic_spring", "delta", delta);
          m.setEffectParam("hysteretic_spring", "hardening", h);
          m.setEffectParam("hysteretic_spring", "hold_order", order);
          std::vector<double> u(6000);
          for (size_t k = 0; k < u.size(); ++k) u[k] = (k / 500) % 2 ? 1e3 : -1e3;
          const auto y = m.simulate(u, 1e-3);
          for (double v : y) ASSERT_TRUE(std::isfinite(v)) << fn << " " << delta << " " << h << " " << order;
        }
}

TEST(HystereticSpring, AModelTakesItOrWhatItRefinesNotBoth) {
  for (const char* other : {"mass_spring", "force_loop"}) {
    model::Model a;
    a.addEffect(other);
    EXPECT_THROW(a.addEffect("hysteretic_spring"), std::invalid_argument) << other;
    model::Model b;
    b.addEffect("hysteretic_spring");
    EXPECT_THROW(b.addEffect(other), std::invalid_argument) << other;
  }
}

// Diagnose on a system of this kind, simulated here (not by the model's code), with other parameters
// than the benchmark's (a lighter payload, another element: linear loading, hardening 1) and another
// excitation (a 3-120 Hz multisine at 1 kHz), sensor noise 0.005 mm: the ladder adds mass_spring, the
// richer form replaces it, and the validated error ends within 1.5x the noise. Left out with
// '-hysteretic_spring', the ladder ends with mass_spring far above it; and hysteretic_spring is never a
// candidate of a round of its own.
TEST(HystereticSpringDiagnose, IsFoundInMassSpringsPlaceOnAnIndependentRecord) {
  const double Ts = 1e-3, noise = 0.005;
  System b;
  b.m = 1.5, b.c = 15.0, b.k = 4e4, b.alpha = 4e4, b.beta = 1.5e3, b.gamma = 0.9, b.delta = 0.9;
  const auto u = multisine(24000, Ts, 11, 3.0, 120.0, 40.0);
  auto y = integrate(b, u, Ts, 2, 40);
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n01(0.0, noise);
  for (double& v : y) v += n01(rng);
  const auto rec = recordOf(u, y, Ts, "hysteretic_spring.csv");

  diagnose::DiagnoseSettings s;
  s.probes = false;
  const auto r = diagnose::diagnose(rec, nullptr, s);
  for (const auto& round : r.rounds)
    for (const auto& c : round) EXPECT_NE(c.effect, "hysteretic_spring") << "tried as a candidate of a round";
  const auto& fin = r.ladder.back();
  std::printf("ladder ends with %zu effects, validated %.5f mm (noise %.3f); %.1f s\n", fin.effects.size(),
              fin.rmse_val, noise, r.seconds);
  ASSERT_EQ(fin.effects, std::vector<std::string>{"hysteretic_spring"});
  EXPECT_TRUE(fin.refined);
  EXPECT_EQ(fin.removed, "mass_spring");
  EXPECT_LE(fin.rmse_val, 1.5 * noise);

  s.candidates = {"-hysteretic_spring"};
  const auto without = diagnose::diagnose(rec, nullptr, s);
  for (const auto& g : without.ladder) EXPECT_FALSE(g.refined);
  EXPECT_GT(without.ladder.back().rmse_val, 3.0 * fin.rmse_val);
}
