// pneumatic_balance: muscle_balance driven by the muscle's own pressure, filled and vented through
// orifices into a volume that grows with the contraction. Its limit (muscle_balance, with a valve that
// follows at once), and the pressure's laws written out here: choked filling at a constant rate, choked
// venting as an exponential approach set by the absolute pressure, and a larger volume filling slower.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <string>
#include <vector>

#include "../common/effect_alone.hpp"
#include "ident/identify.hpp"
#include "model/model.hpp"

using namespace pamc;

namespace {

constexpr double kTs = test::kEffectTs;
using test::alone;
using test::rampsAndHolds;
using test::rms;

// A payload much faster than the pressure, without friction, map or volume change: y follows the pressure
// within a few milliseconds, so the pressure's own law is read off y.
std::map<std::string, double> fastPayload(std::map<std::string, double> pressure) {
  pressure.insert({{"fn", 80.0}, {"zeta", 1.0}, {"zmax", 0.0}, {"w", 0.0}, {"swell", 0.0}});
  return pressure;
}

// u held at `from` for 0.2 s, then at `to`.
std::vector<double> stepInput(double from, double to, size_t n) {
  std::vector<double> u(n, to);
  std::fill(u.begin(), u.begin() + 200, from);
  return u;
}

}  // namespace

// With a valve that follows at once (a huge rate, a narrow band, the supply and the atmosphere far
// outside the motion) and no volume change it is muscle_balance.
TEST(PneumaticBalance, WithAValveThatFollowsAtOnceItIsMuscleBalance) {
  const auto u = rampsAndHolds(0.0, 30.0, 20000, 7);
  const std::map<std::string, double> balance = {{"fn", 5.0},     {"zeta", 0.5}, {"zmax", 0.6}, {"delta", 0.3},
                                                 {"w", 20.0},     {"a1", -0.01}, {"a2", 5e-5},  {"zp", 0.03},
                                                 {"spread", 4.0}, {"lo", -1.0},  {"hi", 28.0}};
  auto fast = balance;
  fast.insert({{"rate", 1e5}, {"band", 0.01}, {"span", 10.0}, {"supply", 1900.0}, {"swell", 0.0}});
  const auto y_mb = alone("muscle_balance", balance).simulate(u, kTs);
  const auto y_pb = alone("pneumatic_balance", fast).simulate(u, kTs);
  EXPECT_LT(rms(y_mb, y_pb), 1e-3) << rms(y_mb, y_pb);
}

// Choked (the muscle's absolute pressure below b times the supply's), filling runs at the constant rate;
// near the supply it slows and stops short of a setpoint above the supply.
TEST(PneumaticBalance, ChokedFillingRunsAtItsRateAndSlowsNearTheSupply) {
  const double rate = 200.0, span = 10.0, supply = 30.0;  // absolute: 10 .. 40 (w = 0: gauge zero at 0)
  const auto m = alone("pneumatic_balance",
                       fastPayload({{"rate", rate}, {"band", 0.01}, {"span", span}, {"supply", supply}, {"b", 0.5}}));
  const auto y = m.simulate(stepInput(0.0, 50.0, 600), kTs);
  // Choked while the absolute pressure is below 0.5 * 40 = 20, i.e. y below 10: a straight ramp.
  const double slope = (y[230] - y[220]) / (10 * kTs);
  EXPECT_NEAR(slope, rate, 0.02 * rate) << y[220] << " " << y[230];
  EXPECT_LT(y[599], supply);                          // never past the supply
  EXPECT_GT(y[599], supply - 1.0);                    // but close to it
  EXPECT_LT(y[420] - y[410], 0.5 * rate * 10 * kTs);  // slower near it
}

// Choked, venting is an exponential approach: the absolute pressure a falls as a' = -rate vent a / a_sup.
TEST(PneumaticBalance, ChokedVentingFallsExponentiallyWithTheAbsolutePressure) {
  const double rate = 100.0, vent = 2.0, span = 5.0, supply = 95.0;  // a_sup = 100
  const auto m = alone(
      "pneumatic_balance",
      fastPayload({{"rate", rate}, {"vent", vent}, {"band", 0.01}, {"span", span}, {"supply", supply}, {"b", 0.3}}));
  const auto y = m.simulate(stepInput(80.0, 0.0, 800), kTs);
  // Choked while span / a < 0.3, a > 16.7 (y > 11.7). Between y = 70 and y = 25 the log of a falls linearly.
  auto timeAt = [&](double level) {
    size_t i = 200;
    while (i < y.size() && y[i] > level) ++i;
    return static_cast<double>(i) * kTs;
  };
  const double t1 = timeAt(70.0), t2 = timeAt(25.0);
  const double tau = (t2 - t1) / std::log((70.0 + span) / (25.0 + span));
  EXPECT_NEAR(tau, 100.0 / (rate * vent), 0.03 * 100.0 / (rate * vent)) << t1 << " " << t2;
  // A straight slew (pressure_lag) would take as long from 70 to 47.5 as from 47.5 to 25; here the upper
  // half is faster.
  EXPECT_LT(timeAt(47.5) - t1, 0.8 * (t2 - timeAt(47.5)));
}

// The volume grows as the muscle contracts: the same valve fills it slower, and the position still
// settles where the map balances.
TEST(PneumaticBalance, ALargerVolumeFillsSlowerAndSettlesAlike) {
  std::map<std::string, double> p = {{"fn", 4.0},   {"zeta", 0.6}, {"zmax", 0.0}, {"w", 20.0},    {"a1", -0.01},
                                     {"rate", 300}, {"band", 2.0}, {"span", 30},  {"supply", 200}};
  const auto u = stepInput(2.0, 25.0, 2500);
  const auto y0 = alone("pneumatic_balance", p).simulate(u, kTs);
  p["swell"] = 0.05;
  p["n"] = 1.4;
  const auto y1 = alone("pneumatic_balance", p).simulate(u, kTs);
  auto riseTime = [&](const std::vector<double>& y) {
    const double target = y[0] + 0.5 * (y.back() - y[0]);
    size_t i = 200;
    while (i < y.size() && y[i] < target) ++i;
    return i;
  };
  EXPECT_GT(riseTime(y1), riseTime(y0) + 10) << riseTime(y0) << " " << riseTime(y1);
  EXPECT_NEAR(y1.back(), y0.back(), 1e-3);
}

// The rising minus the falling branch at the stage input `level` of a triangle 0 -> 40 -> 0 over `seconds`
// (negative by the friction), for a balance whose payload follows within 0.005 mm at 200 s.
double branchGap(const std::map<std::string, double>& extra, double level, double seconds = 200.0) {
  std::map<std::string, double> p = {{"fn", 50.0},   {"zeta", 1.0},  {"zmax", 0.0},      {"w", 10.0}, {"rate", 1e5},
                                     {"band", 0.01}, {"span", 10.0}, {"supply", 1900.0}, {"dc", 0.01}};
  for (const auto& [k, v] : extra) p[k] = v;
  std::vector<double> u(static_cast<size_t>(seconds / kTs));
  for (size_t i = 0; i < u.size(); ++i) {
    const double t = static_cast<double>(i) / static_cast<double>(u.size());
    u[i] = 80.0 * (t < 0.5 ? t : 1.0 - t);
  }
  const auto y = alone("pneumatic_balance", p).simulate(u, kTs);
  const auto up = static_cast<size_t>(level / 80.0 * static_cast<double>(u.size()));
  return y[up] - y[u.size() - 1 - up];
}

// The guide's friction (zc) holds the payload back by its own level wherever the pressure is: on a slow
// triangle the rising and the falling branch differ by 2 zc at a low and at a high pressure alike, while
// the braid's (zp) grows with the pressure.
TEST(PneumaticBalance, TheGuidesFrictionDoesNotGrowWithThePressure) {
  const double zc = 0.4;
  EXPECT_NEAR(branchGap({{"zc", zc}}, 8.0), -2.0 * zc, 0.05 * zc);
  EXPECT_NEAR(branchGap({{"zc", zc}}, 32.0), -2.0 * zc, 0.05 * zc);
  const double braid_low = branchGap({{"zp", 0.01}}, 8.0), braid_high = branchGap({{"zp", 0.01}}, 32.0);
  EXPECT_LT(braid_high, 1.5 * braid_low) << braid_low << " " << braid_high;  // more negative: wider
}

// With a speed width vc the guide's friction builds up with the sliding speed v as zc v / (v + vc): the
// triangle over 200 s slides at 0.4 units/s, where vc 0.4 halves the friction's gap; ten times faster, 91 %
// of it (the gap without the guide, the payload's own lag, taken out).
TEST(PneumaticBalance, TheGuidesFrictionBuildsUpWithTheSlidingSpeed) {
  const double zc = 0.4, vc = 0.4;
  auto friction = [&](double vc_, double seconds) {
    return branchGap({{"zc", zc}, {"vc", vc_}}, 20.0, seconds) - branchGap({}, 20.0, seconds);
  };
  EXPECT_NEAR(friction(vc, 200.0), -zc, 0.1 * zc);
  EXPECT_NEAR(friction(vc, 20.0), -2.0 * zc * 4.0 / 4.4, 0.1 * zc);
  EXPECT_NEAR(friction(0.0, 20.0), -2.0 * zc, 0.1 * zc);
}

// The regulator's opening follows its error with the lag's time constant: choked filling starts later by
// about that time.
TEST(PneumaticBalance, TheOpeningsLagDelaysTheFilling) {
  const double lag = 0.01;
  auto timeTo = [&](double lag_s) {
    const auto m = alone(
        "pneumatic_balance",
        fastPayload({{"rate", 200.0}, {"band", 0.01}, {"span", 10.0}, {"supply", 30.0}, {"b", 0.5}, {"lag", lag_s}}));
    const auto y = m.simulate(stepInput(0.0, 50.0, 600), kTs);
    size_t i = 200;
    while (i < y.size() && y[i] < 5.0) ++i;
    return static_cast<double>(i) * kTs;
  };
  EXPECT_NEAR(timeTo(lag) - timeTo(0.0), lag, 0.2 * lag) << timeTo(0.0) << " " << timeTo(lag);
}

// Along the direction muscle_balance's map leaves open (Effect::scaleAlong) the rests stay where they
// were: the stage input scaled by s, the weight moved, the balance settles at the same position at every
// level - the records' static map cannot tell the two apart, so diagnose searches along it. A map without
// slope has no such direction.
TEST(PneumaticBalance, AlongItsDirectionTheRestsStay) {
  const std::map<std::string, double> params = {{"fn", 5.0},   {"zeta", 0.7},   {"zmax", 0.0},    {"zp", 0.0},
                                                {"w", 10.0},   {"a1", -0.012},  {"a2", 0.0},      {"rate", 1e4},
                                                {"band", 0.5}, {"span", 100.0}, {"supply", 900.0}};
  const auto m = alone("pneumatic_balance", params);
  std::vector<double> u;
  for (const double level : {2.0, 10.0, 18.0, 26.0}) u.insert(u.end(), 3000, level);
  const auto y = m.simulate(u, kTs);
  for (const double s : {1.5, 2.5}) {
    std::vector<double> p(m.effectParams(0), m.effectParams(0) + m.effect(0).params().size());
    ASSERT_TRUE(m.effect(0).scaleAlong(s, 0.0, 30.0, p.data()));
    model::Model scaled = m;
    for (size_t q = 0; q < p.size(); ++q)
      scaled.setEffectParam("pneumatic_balance", m.effect(0).params()[q].name, p[q]);
    EXPECT_GT(std::fabs(p[4] - 10.0), 5.0) << "the weight moves along the direction";
    std::vector<double> us(u);
    for (auto& x : us) x *= s;  // the core's gain scaled with it
    const auto ys = scaled.simulate(us, kTs);
    for (size_t end = 2999; end < u.size(); end += 3000)
      EXPECT_NEAR(ys[end], y[end], 1e-3 * 30.0) << "s " << s << ", level " << u[end];
  }
  auto flat = params;
  flat["a1"] = 0.0;
  const auto f = alone("pneumatic_balance", flat);
  std::vector<double> p(f.effectParams(0), f.effectParams(0) + f.effect(0).params().size());
  EXPECT_FALSE(f.effect(0).scaleAlong(2.0, 0.0, 30.0, p.data()));
}

// The gas's law is what the position holds weakly (Effect::weaklyHeld): diagnose polishes its final model
// once more from it at the catalogue's defaults, scaled to the record as their boxes are (docs/MODELING.md,
// "The gas's law from its defaults"). The rest of the model stays; a model without such an effect has none.
TEST(PneumaticBalance, ItsGasLawStartsAgainFromTheDefaultsScaledToTheRecord) {
  const auto m =
      alone("pneumatic_balance",
            {{"span", 300.0}, {"supply", 500.0}, {"b", 0.9}, {"n", 1.0}, {"w", 20.0}, {"fn", 7.0}, {"rate", 900.0}});
  io::Measurement d;  // 80 mm over 7.5 V: twice the catalogue's 40 mm rig
  d.Ts = kTs;
  for (int i = 0; i < 1000; ++i) {
    d.t.push_back(i * kTs);
    d.u.push_back(-3.5 + 7.5 * i / 999.0);
    d.y.push_back(80.0 * i / 999.0);
  }
  std::string names;
  const auto r = ident::withWeakDefaults(m, d, &names);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(names, "pneumatic_balance's span, supply, b, n");
  const auto value = [](const model::Model& x, const std::string& name) -> double {
    const auto specs = x.paramSpecs();
    const auto p = x.params();
    for (size_t i = 0; i < specs.size(); ++i)
      if (specs[i].name == "pneumatic_balance." + name) return p[i];
    ADD_FAILURE() << name;
    return std::nan("");
  };
  EXPECT_DOUBLE_EQ(value(*r, "span"), 25.0 * 2.0);  // the atmosphere and the supply in the record's units
  EXPECT_DOUBLE_EQ(value(*r, "supply"), 200.0 * 2.0);
  EXPECT_DOUBLE_EQ(value(*r, "b"), 0.3);
  EXPECT_DOUBLE_EQ(value(*r, "n"), 1.2);
  for (const char* kept : {"w", "fn", "rate", "band", "vent", "swell"})
    EXPECT_EQ(value(*r, kept), value(m, kept)) << kept;
  EXPECT_EQ(r->core().k, m.core().k);
  EXPECT_FALSE(ident::withWeakDefaults(alone("muscle_balance", {}), d).has_value());
}
