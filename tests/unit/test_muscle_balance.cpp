// muscle_balance: the force balance of a muscle over its whole stroke - its force-length-pressure map, the
// braid friction of several break-away levels growing with the pressure, the end stops. Its limit
// (force_loop), its static equilibrium (solved here by bisection), the stops, the friction's growth with
// the pressure (its cycle without allocation: test_alloc.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "diagnose/diagnosis.hpp"
#include "../common/effect_alone.hpp"
#include "model/model.hpp"

using namespace pamc;

namespace {

constexpr double kTs = test::kEffectTs;
using test::alone;
using test::rampsAndHolds;
using test::rms;

// The balance's static position without friction, (in + w)(1 + a1 y + a2 y^2) - w - y = 0, by bisection.
double staticPosition(double in, double w, double a1, double a2) {
  auto f = [&](double y) { return (in + w) * (1.0 + a1 * y + a2 * y * y) - w - y; };
  double lo = -100.0, hi = 100.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > 0.0 ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

// A rung of `effects` with `effect` refined into `by`: the model is built, and `by` is all that is left.
void expectAloneInTheirPlace(const std::vector<std::string>& effects, const std::string& effect, const std::string& by) {
  diagnose::Rung rung;
  rung.effects = effects;
  for (const auto& e : rung.effects) rung.model.addEffect(e);
  model::Model m;
  ASSERT_NO_THROW(m = diagnose::detail::withReplacement(rung, effect, by));
  EXPECT_TRUE(m.hasEffect(by));
  for (const auto& e : effects) EXPECT_FALSE(m.hasEffect(e)) << e;
}

}  // namespace

// With a straight map, friction that does not grow with the pressure, one break-away level and no stops
// it is force_loop (its own integration: within a small fraction of the travel).
TEST(MuscleBalance, WithoutItsMapSpreadAndStopsItIsForceLoop) {
  const auto u = rampsAndHolds(0.0, 30.0, 20000, 5);
  const std::map<std::string, double> shared = {{"fn", 6.0}, {"zeta", 0.4}, {"zmax", 0.8}, {"delta", 0.3}};
  const auto y_fl = alone("force_loop", shared).simulate(u, kTs);
  const auto y_mb = alone("muscle_balance", shared).simulate(u, kTs);
  const double span = *std::max_element(y_fl.begin(), y_fl.end()) - *std::min_element(y_fl.begin(), y_fl.end());
  EXPECT_LT(rms(y_fl, y_mb), 2e-3 * span) << rms(y_fl, y_mb);
}

// Held, without friction, the payload settles where the map's force balances the spring and the weight.
TEST(MuscleBalance, HeldItRestsWhereTheMapBalances) {
  const double w = 20.0, a1 = -0.015, a2 = 8e-5;
  const std::map<std::string, double> p = {{"fn", 5.0}, {"zeta", 0.6}, {"zmax", 0.0}, {"w", w}, {"a1", a1}, {"a2", a2}};
  for (const double in : {2.0, 15.0, 35.0}) {
    std::vector<double> u(6000, in);
    u.insert(u.begin(), 10, 0.0);  // from rest at 0, a step to in
    const auto y = alone("muscle_balance", p).simulate(u, kTs);
    EXPECT_NEAR(y.back(), staticPosition(in, w, a1, a2), 1e-6) << in;
    // The map stiffens the muscle as it contracts: less travel than the straight balance's.
    if (in > 5.0) {
      EXPECT_LT(y.back(), in) << in;
    }
  }
}

TEST(MuscleBalance, APayloadPushedIntoAStopRestsOnIt) {
  const std::map<std::string, double> p = {{"fn", 8.0}, {"zeta", 0.2}, {"zmax", 0.2}, {"lo", 0.0}, {"hi", 25.0}};
  std::vector<double> u(3000, 10.0);
  std::fill(u.begin() + 500, u.begin() + 1500, 40.0);  // into the upper stop
  std::fill(u.begin() + 1500, u.end(), -20.0);         // into the lower stop
  const auto y = alone("muscle_balance", p).simulate(u, kTs);
  EXPECT_NEAR(y[490], 10.0, 1e-3);
  EXPECT_DOUBLE_EQ(y[1400], 25.0);  // resting: no bounce off the stop
  EXPECT_DOUBLE_EQ(y[1499], 25.0);
  EXPECT_DOUBLE_EQ(y[2900], 0.0);
  for (const double v : y) EXPECT_TRUE(v >= 0.0 && v <= 25.0) << v;
}

// The loop's width (the position falling against rising at the same input, slow triangles of +-8 about a
// level) grows with the pressure when the friction does (zp: by 2 zp level), and not without it.
TEST(MuscleBalance, TheFrictionGrowsWithThePressure) {
  auto width = [](double zp, double centre) {
    const std::map<std::string, double> p = {{"fn", 10.0}, {"zeta", 0.7}, {"zmax", 0.3}, {"delta", 0.2}, {"zp", zp}};
    std::vector<double> u;
    for (int k = 0; k < 2; ++k) {
      for (int i = 0; i < 8000; ++i) u.push_back(centre - 8.0 + 16.0 * i / 8000.0);
      for (int i = 0; i < 8000; ++i) u.push_back(centre + 8.0 - 16.0 * i / 8000.0);
    }
    const auto y = alone("muscle_balance", p).simulate(u, kTs);
    return y[u.size() - 4000] - y[u.size() - 12000];  // at the centre: falling minus rising
  };
  const double w0_low = width(0.0, 10.0), w0_high = width(0.0, 30.0);
  EXPECT_NEAR(w0_low, w0_high, 1e-3);
  // 2 zmax, the Dahl loop's width, plus the viscous lag of each branch, (2 zeta / wn) times the rate 2 /s.
  EXPECT_NEAR(w0_low, 2 * 0.3 + 2 * (2 * 0.7 / (2 * M_PI * 10.0)) * 2.0, 0.01);
  EXPECT_NEAR(width(0.05, 10.0) - w0_low, 2 * 0.05 * 10.0, 0.05);
  EXPECT_NEAR(width(0.05, 30.0) - w0_high, 2 * 0.05 * 30.0, 0.05);
}

// Several break-away levels: with its travels spread, the elements with longer travels are still loading
// after a reversal - the payload travels back further before the friction holds it; the loop's full width
// stays 2 zmax.
TEST(MuscleBalance, SpreadTravelsRoundTheReversal) {
  auto afterReversal = [](double spread) {
    const std::map<std::string, double> p = {
        {"fn", 10.0}, {"zeta", 0.7}, {"zmax", 0.5}, {"delta", 0.1}, {"spread", spread}};
    std::vector<double> u;
    for (int i = 0; i < 8000; ++i) u.push_back(10.0 * i / 8000.0);
    for (int i = 0; i < 8000; ++i) u.push_back(10.0 - 10.0 * i / 8000.0);
    const auto y = alone("muscle_balance", p).simulate(u, kTs);
    return std::make_pair(y[7999] - y[8400], y[7999] - y[15999] - 10.0);  // travel back after 0.5 V; the loop's end
  };
  const auto one = afterReversal(1.0), spread = afterReversal(16.0);
  EXPECT_GT(spread.first, 2.0 * one.first);
  EXPECT_NEAR(spread.second, one.second, 0.01);
  EXPECT_NEAR(one.second, -2 * 0.5, 0.08);
}

// In the place of one effect it refines, the balance takes the others it refines and those it absorbs as
// well: a rung of saturation + friction_hysteresis + force_loop (where diagnose ends on the paper's u0
// record) becomes muscle_balance alone, with no model refusing two alternatives for the same physics.
TEST(MuscleBalance, InOneEffectsPlaceItTakesTheOthersItStandsFor) {
  expectAloneInTheirPlace({"saturation", "friction_hysteresis", "force_loop"}, "friction_hysteresis", "muscle_balance");
}

// In friction_hysteresis's place the balance starts from the fits of all it stands for: the friction's
// level and travel from friction_hysteresis, the payload's frequency and damping - which
// friction_hysteresis lacks - from force_loop's fit, not the catalogue's defaults.
TEST(MuscleBalance, InOneEffectsPlaceItTakesWhatThatOneLacksFromTheOthersFits) {
  diagnose::Rung rung;
  rung.effects = {"saturation", "friction_hysteresis", "force_loop"};
  for (const auto& e : rung.effects) rung.model.addEffect(e);
  const std::map<std::pair<std::string, std::string>, double> fitted = {
      {{"friction_hysteresis", "zmax"}, 3.0}, {{"friction_hysteresis", "delta"}, 2.5}, {{"force_loop", "fn"}, 4.0},
      {{"force_loop", "zeta"}, 0.7},          {{"force_loop", "zmax"}, 0.1},           {{"force_loop", "delta"}, 0.02}};
  for (const auto& [which, v] : fitted) rung.model.setEffectParam(which.first, which.second, v);
  const auto m = diagnose::detail::withReplacement(rung, "friction_hysteresis", "muscle_balance");
  const auto value = [&](const std::string& name) {
    const auto& specs = m.effect(0).params();
    for (size_t q = 0; q < specs.size(); ++q)
      if (specs[q].name == name) return m.effectParams(0)[q];
    return std::nan("");
  };
  ASSERT_EQ(m.numEffects(), 1);
  EXPECT_EQ(value("zmax"), 3.0);  // the replaced effect's own, where both have it
  EXPECT_EQ(value("delta"), 2.5);
  EXPECT_EQ(value("fn"), 4.0);  // force_loop's, where friction_hysteresis has none
  EXPECT_EQ(value("zeta"), 0.7);
}

// Down the chain as well: pneumatic_balance in pressure_lag's place (a rung the oracle's closed-loop plant
// gave: pressure_lag + force_loop + saturation) takes force_loop, which muscle_balance refines, and
// saturation, which it absorbs - with force_loop kept the model would carry four estimator states.
TEST(MuscleBalance, ARicherFormTakesWhatItsOwnRefinementsStandFor) {
  expectAloneInTheirPlace({"pressure_lag", "force_loop", "saturation"}, "pressure_lag", "pneumatic_balance");
}

// Effect::seedRest: a refinement that absorbs saturation starts its map where the rung's rest is. A rest
// curve of the balance's own law comes back to within 0.1 % of its span; a saturation's curve gets the
// nearest convex map (a2 >= 0, as a muscle's is), nearer than the straight spring it started as. An
// effect without a map has nothing to seed.
TEST(MuscleBalance, ItsMapIsSeededFromARestCurve) {
  std::vector<double> xs, own, sat;
  for (int k = 0; k <= 40; ++k) {
    xs.push_back(k);
    own.push_back(staticPosition(k, 30.0, -0.015, 8e-5));
    sat.push_back(35.0 * std::tanh(k / 35.0));
  }
  const auto m = alone("muscle_balance", {{"fn", 5.0}});
  const auto seeded = [&](const std::vector<double>& ys) {
    std::vector<double> p(m.effectParams(0), m.effectParams(0) + m.effect(0).params().size());
    EXPECT_TRUE(m.effect(0).seedRest(xs, ys, p.data()));
    EXPECT_GE(p[6], 0.0) << "a2";
    double worst = 0.0;
    for (size_t i = 0; i < xs.size(); ++i)
      worst = std::max(worst, std::fabs(staticPosition(xs[i], p[4], p[5], p[6]) - ys[i]));
    return worst;
  };
  EXPECT_LT(seeded(own), 1e-3 * (own.back() - own.front()));
  double straight = 0.0;
  for (size_t i = 0; i < xs.size(); ++i) straight = std::max(straight, std::fabs(xs[i] - sat[i]));
  EXPECT_LT(seeded(sat), 0.5 * straight);
  const auto f = alone("force_loop", {{"fn", 5.0}});
  std::vector<double> p(f.effectParams(0), f.effectParams(0) + f.effect(0).params().size());
  EXPECT_FALSE(f.effect(0).seedRest(xs, sat, p.data()));
}
