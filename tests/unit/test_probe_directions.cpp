// The probes' direction-dependent versions on data: physics outside the catalogue that differs between
// a rising and a falling command, simulated here from its equations (core and valve written out in this
// file, sharing no code with the model's effects or probes), and diagnose's last step - the top probe
// fitted once more with separate parameters rising and falling - taken and said in words.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <string>

#include "control/trajectory.hpp"
#include "diagnose/diagnose.hpp"
#include "model/model.hpp"
#include "model/probe.hpp"

using namespace pamc;

namespace {

// The core's parameters (Bouc-Wen, m = 1): k, rho, b, alpha, beta, gamma.
constexpr double kK = 5.0, kRho = 0.7, kB = 16.0, kAlpha = 1.0, kBeta = 0.4, kGamma = 0.2;
constexpr double kNoise = 0.005;  // sensor noise, rms
constexpr int kSubsteps = 10;     // RK4 steps per sample

// A valve that fills the muscle through its supply port and vents it through a smaller exhaust: orifice
// flow, the pressure (in command units, p) moving towards the command u at c (u - p) / sqrt(|u - p| + eps)
// - the square-root law of turbulent flow, linear (laminar) within eps - with c = 18 filling (u > p) and 6
// venting. The core follows p: dh/dt = alpha p' - beta p' |h| - gamma |p'| h, y = k rho p + b + k (1 - rho) h.
struct State {
  double p, h;
};
constexpr double kFill = 18.0, kVent = 6.0, kEps = 0.01;

// Which coefficient the valve uses: by the sign of u - p (filling or venting: the physics), or by the
// direction the command last moved in (what the probe's direction-dependent version does).
enum class Switch { Flow, Command };

// rising: the command's last direction (used with Switch::Command only).
State rate(const State& x, double u, Switch sw = Switch::Flow, bool rising = true) {
  const double e = u - x.p;
  const bool filling = sw == Switch::Flow ? e > 0 : rising;
  const double dp = (filling ? kFill : kVent) * e / std::sqrt(std::fabs(e) + kEps);
  return {dp, kAlpha * dp - kBeta * dp * std::fabs(x.h) - kGamma * std::fabs(dp) * x.h};
}

// Classical RK4 in time over [t, t + dt], the command read from the continuous ramp-hold trajectory.
State rk4(const State& x, const control::Trajectory& traj, double t, double dt, Switch sw, bool rising) {
  auto add = [](const State& a, const State& d, double f) { return State{a.p + f * d.p, a.h + f * d.h}; };
  const State k1 = rate(x, traj.at(t), sw, rising), k2 = rate(add(x, k1, dt / 2), traj.at(t + dt / 2), sw, rising);
  const State k3 = rate(add(x, k2, dt / 2), traj.at(t + dt / 2), sw, rising);
  const State k4 = rate(add(x, k3, dt), traj.at(t + dt), sw, rising);
  return {x.p + dt / 6 * (k1.p + 2 * k2.p + 2 * k3.p + k4.p), x.h + dt / 6 * (k1.h + 2 * k2.h + 2 * k3.h + k4.h)};
}

io::Measurement fillsFasterThanItVents(std::uint64_t seed, double seconds, Switch sw = Switch::Flow) {
  const auto traj = control::Trajectory::randomRampHold(seed, -2.5, 2.5);
  io::Measurement d;
  d.source = "orifice flow, 18 filling and 6 venting, seed " + std::to_string(seed);
  d.Ts = 1e-3;
  const auto n = static_cast<size_t>(seconds / d.Ts);
  std::mt19937_64 rng(seed + 7);
  std::normal_distribution<double> noise(0.0, kNoise);
  State x{traj.at(0.0), 0.0};
  bool rising = true;
  for (size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) * d.Ts;
    if (i > 0 && traj.at(t) != traj.at(t - d.Ts)) rising = traj.at(t) > traj.at(t - d.Ts);  // held while it holds
    if (i > 0)
      for (int k = 0; k < kSubsteps; ++k)
        x = rk4(x, traj, t - d.Ts + k * d.Ts / kSubsteps, d.Ts / kSubsteps, sw, rising);
    d.t.push_back(t);
    d.u.push_back(traj.at(t));
    d.y.push_back(kK * kRho * x.p + kB + kK * (1.0 - kRho) * x.h + noise(rng));
  }
  return d;
}

// The fitted parameter `name` of the direction-dependent probe in the model (NaN when absent).
double param(const model::Model& m, const std::string& effect, const std::string& name) {
  for (int i = 0; i < m.numEffects(); ++i) {
    if (m.effect(i).name() != effect) continue;
    const auto& specs = m.effect(i).params();
    for (size_t q = 0; q < specs.size(); ++q)
      if (specs[q].name == name) return m.effectParams(i)[q];
  }
  return NAN;
}

std::string table(const diagnose::DiagnoseResult& r) {
  std::string s = r.verdict + "\nprobes:";
  for (const auto& p : r.probes)
    s += "\n  " + p.label() + " " + std::to_string(p.rmse_val) + " " + std::to_string(p.explains);
  return s;
}

}  // namespace

// Orifice flow 3x faster filling than venting, on three pairs of records (train, validate): the
// orifice-flow probe is the top probe, goes in its direction-dependent version with the valve's
// coefficients and brings the validated error to the noise; where the catalogue took the lag rising and
// falling (pressure_lag_updown), in its place. One row per pair: the first three were fixed before the
// lags switched on the flow (Effect::followsInput), when two of them failed; the last four were added
// after it, before anything else was tried on them. Where the catalogue ends at a payload's dynamics
// (force_loop, mass_spring), which no probe overlaps, the valve is not named: seeds 21/22 (no probe
// explains anything), 41/42 (direction_lag in its place explains half), 71/72. Those rows say so (`named`
// false: not valve_flow at the noise) and fail once that changes, so that docs/MODELING.md is brought up
// to date with it. Seeds 11/12 and 61/62 changed so when the warm starts of a scale spanning decades were
// also spread in its logarithm (ident::fit): the catalogue then finds the lag's short rising time
// constant, ends at pressure_lag_updown, and the probe goes in its place.
struct ValvePair {
  std::uint64_t train, val;
  const char* replaces;  // the effect the probe is expected in place of ("" on top of the model)
  bool named;            // false: a known miss above
};
class OrificeFlow : public ::testing::TestWithParam<ValvePair> {};

TEST_P(OrificeFlow, TheProbeNamesItAndItsRisingFallingVersionReachesTheNoise) {
  const auto pair = GetParam();
  const auto train = fillsFasterThanItVents(pair.train, 24.0), val = fillsFasterThanItVents(pair.val, 16.0);
  diagnose::DiagnoseSettings s;
  s.method = ident::FitMethod::MultiStart;
  const auto r = diagnose::diagnose(train, &val, s);
  std::string fin;
  for (const auto& e : r.ladder.back().effects) fin += " + " + e;
  ASSERT_FALSE(r.probes.empty()) << r.verdict;
  const auto& top = r.probes.front();
  std::printf(
      "seeds %llu/%llu: catalogue ends at reference model%s, validated %.4g; top probe %s: symmetric %.4g, "
      "train %.4g, validated %.4g (noise %.3g); rate %.3g rising, %.3g falling\n",
      static_cast<unsigned long long>(pair.train), static_cast<unsigned long long>(pair.val), fin.c_str(),
      r.ladder.back().rmse_val, top.label().c_str(), top.symmetric_rmse_val, top.rmse_train, top.rmse_val, kNoise,
      param(top.model, "valve_flow_updown", "rate_up"), param(top.model, "valve_flow_updown", "rate_down"));
  if (!pair.named) {
    EXPECT_FALSE(top.probe == "valve_flow" && top.rmse_val < 1.5 * kNoise) << table(r);
    return;
  }
  EXPECT_EQ(top.probe, "valve_flow") << table(r);
  EXPECT_EQ(top.replaces, pair.replaces) << table(r);
  EXPECT_FALSE(top.direction.empty()) << table(r);
  EXPECT_TRUE(r.probe_rung) << table(r);
  EXPECT_LT(top.rmse_train, 3 * kNoise) << table(r);
  EXPECT_LT(top.rmse_val, 1.5 * kNoise) << table(r);
  // Taken by the directions step (on top of the model): it lowered the symmetric fit's validated RMSE by
  // min_gain. In the place of a lag rising and falling the probe went in its own version at once.
  if (top.symmetric_rmse_val > 0) {
    EXPECT_LE(top.rmse_val, (1.0 - s.min_gain) * top.symmetric_rmse_val) << table(r);
  }
  if (*pair.replaces) {
    EXPECT_NE(r.verdict.find(std::string("(in place of ") + pair.replaces + ")"), std::string::npos) << r.verdict;
  }
  EXPECT_NEAR(param(top.model, "valve_flow_updown", "rate_up"), kFill, 0.1 * kFill) << table(r);
  EXPECT_NEAR(param(top.model, "valve_flow_updown", "rate_down"), kVent, 0.1 * kVent) << table(r);
  EXPECT_NE(r.verdict.find("separate parameters rising and falling, valve_flow with rate"), std::string::npos)
      << r.verdict;
}

INSTANTIATE_TEST_SUITE_P(ProbeDirections, OrificeFlow,
                         ::testing::Values(ValvePair{11, 12, "pressure_lag_updown", true}, ValvePair{21, 22, "", false},
                                           ValvePair{31, 32, "pressure_lag_updown", true}, ValvePair{41, 42, "", false},
                                           ValvePair{51, 52, "pressure_lag_updown", true},
                                           ValvePair{61, 62, "pressure_lag_updown", true},
                                           ValvePair{71, 72, "", false}),
                         [](const ::testing::TestParamInfo<ValvePair>& i) {
                           return "seeds" + std::to_string(i.param.train) + "and" + std::to_string(i.param.val);
                         });

// A probe that may take an effect's place may take its direction-dependent version's too.
TEST(ProbeDirections, AProbeStandsForItsEffectsDirectionDependentVersion) {
  EXPECT_TRUE(model::findProbe("valve_flow")->standsFor("pressure_lag_updown"));
  EXPECT_TRUE(model::findProbe("valve_flow")->standsFor("pressure_lag"));
  EXPECT_FALSE(model::findProbe("valve_flow")->standsFor("creep_updown"));
  EXPECT_FALSE(model::findProbe("valve_flow")->standsFor("_updown"));
}

// The probe's direction-dependent version switches like the valve, on the sign of u - p: the core and
// the probe at the valve's own coefficients (18 rising, 6 falling), no fit, on the six records above, made
// once with the valve switching by the sign of u - p (the physics) and once by the command's last
// direction. Near the noise on every record of the physics; the record that turns the command often
// before the pressure has caught up (seed 32) shows how far apart the two rules are.
TEST(ProbeDirections, TheProbeSwitchesOnTheFlowLikeTheValve) {
  model::Model m({kK, kRho, kB, kAlpha, kBeta, kGamma});
  m.addEffect("valve_flow_updown");
  m.setEffectParam("valve_flow_updown", "rate_up", kFill);
  m.setEffectParam("valve_flow_updown", "rate_down", kVent);
  auto rmse = [&](const io::Measurement& d) {
    const auto y = m.simulate(d.u, d.Ts);
    double ss = 0.0;
    for (size_t k = 0; k < y.size(); ++k) ss += (y[k] - d.y[k]) * (y[k] - d.y[k]);
    return std::sqrt(ss / static_cast<double>(y.size()));
  };
  double command32 = 0.0;
  for (const std::uint64_t seed : {11, 12, 21, 22, 31, 32}) {
    const double seconds = seed % 2 == 1 ? 24.0 : 16.0;
    const double flow = rmse(fillsFasterThanItVents(seed, seconds, Switch::Flow));
    const double command = rmse(fillsFasterThanItVents(seed, seconds, Switch::Command));
    std::printf(
        "seed %llu: the probe at 18 / 6 misses the valve switching by flow by %.4f, by the command's direction by "
        "%.4f\n",
        static_cast<unsigned long long>(seed), flow, command);
    EXPECT_LT(flow, 3 * kNoise) << seed;
    if (seed == 32) command32 = command;
  }
  EXPECT_GT(command32, 3 * kNoise);
}
