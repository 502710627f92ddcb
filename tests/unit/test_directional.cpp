// Direction-dependent versions: "<effect>_updown" carries each parameter for a rising and a falling
// input and switches between them over the same states; diagnose tries it for the direction-dependent
// effects of its final model and says in words what differs.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "control/trajectory.hpp"
#include "diagnose/diagnose.hpp"
#include "model/effect.hpp"
#include "model/model.hpp"

using namespace pamc;

TEST(Directional, EachDirectionRunsWithItsOwnParameters) {
  const auto e = model::makeEffect("pressure_lag_updown");
  ASSERT_EQ(e->params().size(), 4u);
  EXPECT_EQ(e->params()[0].name, "tau_up");
  EXPECT_EQ(e->params()[2].name, "tau_down");
  const double p[4] = {0.01, 1000.0, 0.1, 1000.0};  // tau up 10 ms, down 100 ms; no slew limit
  std::vector<double> s(static_cast<size_t>(e->numStates()));
  model::StepContext c;
  e->init(p, s.data(), 0.0, c);
  double y = 0;
  for (int k = 0; k < 10; ++k) y = e->step(p, s.data(), 1.0, c);  // one tau_up after a step up
  EXPECT_NEAR(y, 1.0 - std::exp(-1.0), 0.01);
  for (int k = 0; k < 400; ++k) e->step(p, s.data(), 1.0, c);
  for (int k = 0; k < 100; ++k) y = e->step(p, s.data(), 0.0, c);  // one tau_down after a step down
  EXPECT_NEAR(y, std::exp(-1.0), 0.01);
  EXPECT_THROW(model::makeEffect("saturation_updown"), std::invalid_argument);
  EXPECT_STREQ(e->alternativeTo(), "pressure_lag");
}

// A lag's version switches like a valve: on whether the command is above the pressure (filling) or
// below it (venting), not on the command's own direction - a command that turns down before the
// pressure has caught up still fills.
TEST(Directional, ALagSwitchesOnTheFlowNotOnTheCommandsDirection) {
  const auto e = model::makeEffect("pressure_lag_updown");
  const double p[4] = {0.01, 1000.0, 0.1, 1000.0};  // tau up 10 ms, down 100 ms; no slew limit
  std::vector<double> s(static_cast<size_t>(e->numStates()));
  model::StepContext c;
  e->init(p, s.data(), 0.0, c);
  double y = 0;
  for (int k = 0; k < 5; ++k) y = e->step(p, s.data(), 1.0, c);  // half a tau_up: the pressure near 0.39
  const double filling = y + (0.8 - y) * (1.0 - std::exp(-c.Ts / 0.01));
  EXPECT_NEAR(e->step(p, s.data(), 0.8, c), filling, 1e-12);  // the command falls, still above the pressure
  for (int k = 0; k < 100; ++k) y = e->step(p, s.data(), 0.8, c);
  const double venting = y + (0.5 - y) * (1.0 - std::exp(-c.Ts / 0.1));
  EXPECT_NEAR(e->step(p, s.data(), 0.5, c), venting, 1e-12);  // below the pressure: venting
  EXPECT_TRUE(model::makeEffect("valve_flow")->followsInput());
  EXPECT_FALSE(model::makeEffect("creep")->followsInput());  // creep: loading and unloading by the input
}

namespace {

// The core on an input that reaches it through a lag of 20 ms rising and 120 ms falling, written out
// here (not the effect's code), sensor noise 0.005 rms.
io::Measurement asymmetricLagData(std::uint64_t seed, double seconds) {
  const auto traj = control::Trajectory::randomRampHold(seed, -2.5, 2.5);
  io::Measurement d;
  d.source = "asymmetric lag seed " + std::to_string(seed);
  d.Ts = 1e-3;
  const auto n = static_cast<size_t>(seconds / d.Ts);
  std::vector<double> ue(n);
  double p = traj.at(0.0);
  for (size_t i = 0; i < n; ++i) {
    d.t.push_back(static_cast<double>(i) * d.Ts);
    d.u.push_back(traj.at(d.t.back()));
    const double tau = d.u.back() > p ? 0.02 : 0.12;
    p += (d.u.back() - p) * (1.0 - std::exp(-d.Ts / tau));
    ue[i] = p;
  }
  d.y = model::Model(model::BoucWenParams{5.0, 0.7, 16.0, 1.0, 0.4, 0.2}).simulate(ue, d.Ts);
  std::mt19937_64 rng(seed + 7);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (auto& y : d.y) y += noise(rng);
  return d;
}

}  // namespace

TEST(Directional, DiagnoseSaysTheMuscleFillsFasterThanItVents) {
  const auto train = asymmetricLagData(11, 24.0), val = asymmetricLagData(12, 16.0);
  diagnose::DiagnoseSettings s;
  s.candidates = {"pressure_lag"};
  s.method = ident::FitMethod::MultiStart;
  s.probes = false;
  s.log = [](const std::string& m) { std::printf("%s\n", m.c_str()); };
  const auto r = diagnose::diagnose(train, &val, s);
  const auto& fin = r.ladder.back();
  ASSERT_EQ(fin.effects.size(), 1u) << r.verdict;
  EXPECT_EQ(fin.effects[0], "pressure_lag_updown") << r.verdict;
  EXPECT_NE(r.verdict.find("fills faster than it vents"), std::string::npos) << r.verdict;
  EXPECT_LT(fin.rmse_val, 0.5 * r.ladder[r.ladder.size() - 2].rmse_val) << r.verdict;
}
