// The AMC's estimator with a model whose output lags the hysteresis state (mass_spring, creep): those
// effects' states are in the UKF's state, so the filter knows how h reaches the position over the
// following samples. Without them P_h grew without bound on clean data and the estimate ran off by
// metres (docs/RELIABILITY.md, "The estimator with output dynamics"). Plus the divergence guard: a
// filter whose posterior misses a used position by more than `diverge` restarts and says so.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <cmath>

#include "estimation/active_model.hpp"
#include "model/model.hpp"
#include "plant/plant.hpp"

using namespace pamc;

namespace {
constexpr double kTs = 1e-3;

double command(long k) {
  // A sine with a square on top: fast edges ring the 6 Hz mass-spring, within the stroke.
  return 0.8 * std::sin(2 * M_PI * 0.5 * static_cast<double>(k) * kTs) + (k % 3000 < 1500 ? 0.5 : -0.5);
}

bool spd(const estimation::ActiveModel::Filter::Mat& P) {
  using PMat = estimation::ActiveModel::Filter::Mat;
  const Eigen::SelfAdjointEigenSolver<PMat> es(P, Eigen::EigenvaluesOnly);
  return P.allFinite() && P == P.transpose() && Eigen::LLT<PMat>(P).info() == Eigen::Success &&
         es.eigenvalues().minCoeff() > 0.0;
}
}  // namespace

TEST(OutputDynamics, TheModelNamesTheStatesTheFilterCarries) {
  model::Model m;
  EXPECT_EQ(m.numFilterStates(), 0);
  m.addEffect("friction_hysteresis");  // direct path: none
  m.addEffect("pressure_lag");         // input effect: none
  EXPECT_EQ(m.numFilterStates(), 0);
  m.addEffect("mass_spring");
  EXPECT_EQ(m.numFilterStates(), 2);
  m.addEffect("creep");
  ASSERT_EQ(m.numFilterStates(), 3);
  // Chain order (creep before mass_spring), each pointing at its effect's leading states.
  model::Model::State st;
  model::StepContext c;
  m.init(st, 1.0, c);
  const double y0 = st.s[static_cast<size_t>(m.filterStateIndex(1))];  // mass_spring's y at rest
  EXPECT_NEAR(y0, m.outputPeek(st, m.coreOutput(st.u_eff_prev, st.h), c), 1e-9);
  // outputWith with the model's own states is outputPeek, and it reports the states after the sample.
  double xf[model::kMaxFilterStates], next[model::kMaxFilterStates];
  for (int i = 0; i < 3; ++i) xf[i] = st.s[static_cast<size_t>(m.filterStateIndex(i))];
  const double y_core = m.coreOutput(st.u_eff_prev, st.h) + 2.0;  // a step into the chain
  EXPECT_DOUBLE_EQ(m.outputWith(st, xf, next, y_core, c), m.outputPeek(st, y_core, c));
  model::Model::State adv = st;
  m.outputStage(adv, y_core, c);
  for (int i = 0; i < 3; ++i) EXPECT_DOUBLE_EQ(next[i], adv.s[static_cast<size_t>(m.filterStateIndex(i))]) << i;
  // Other values in, other output out: the states are taken from xf, not st.
  xf[1] += 1.0;
  EXPECT_GT(std::fabs(m.outputWith(st, xf, nullptr, y_core, c) - m.outputPeek(st, y_core, c)), 0.5);
}

// The estimator on the plant's own model against the plant, `samples` of a command that rings the
// output dynamics: a reset or a covariance that is not positive definite fails the test where it happens.
namespace {
struct FilterRun {
  double rmse = 0.0, max_err = 0.0, max_ph = 0.0;
  unsigned resets = 0;
};
FilterRun followThePlant(const plant::PlantConfig& pc, long samples) {
  FilterRun r;
  plant::Plant plant(pc);
  estimation::ActiveModel am;
  am.configure(pc.truth, estimation::ActiveModelSettings{}, kTs);
  plant.reset(command(0));
  am.reset(command(0));
  double e2 = 0.0;
  long n = 0;
  for (long k = 0; k < samples; ++k) {
    const double u = command(k);
    const double y_true = plant.step(u);
    const auto st = am.update(u, plant.measure());
    if (st.status == estimation::UkfStatus::Reset) {
      ADD_FAILURE() << "the filter reset at sample " << k;
      break;
    }
    if (k % 1000 == 0 && !spd(am.covariance())) {
      ADD_FAILURE() << "covariance not positive definite at sample " << k;
      break;
    }
    if (k < 2000) continue;  // the filter's first settling
    e2 += (st.y_post - y_true) * (st.y_post - y_true);
    r.max_err = std::max(r.max_err, std::fabs(st.y_post - y_true));
    r.max_ph = std::max(r.max_ph, am.covariance()(0, 0));
    ++n;
  }
  r.rmse = std::sqrt(e2 / static_cast<double>(std::max(n, 1L)));
  r.resets = am.resets();
  return r;
}
}  // namespace

// The emulator's whole model (pressure lag, load, saturation, friction, 6 Hz mass-spring) as the
// filter's model, the emulator as the plant, 200 s of a command that rings the mass-spring: P stays
// bounded and positive definite, the estimate follows the true position, the filter never resets.
TEST(OutputDynamics, TheFilterStaysBoundedAndFollowsTheWholeEmulatorModel) {
  const auto pc = plant::PlantConfig::modelDefaults();
  ASSERT_TRUE(pc.truth.hasEffect("mass_spring"));
  const auto r = followThePlant(pc, 200'000);
  RecordProperty("estimate_rmse_mm", std::to_string(r.rmse));
  RecordProperty("max_P_h", std::to_string(r.max_ph));
  std::printf("whole emulator model, 200 s: estimate RMSE %.4f mm (max %.3f mm), largest P_h %.3g, resets %u\n", r.rmse,
              r.max_err, r.max_ph, r.resets);
  EXPECT_LT(r.rmse, 0.05);
  EXPECT_LT(r.max_err, 0.5);
  EXPECT_LT(r.max_ph, 100.0);  // bounded: without the filter states it grew by Q_h every sample
  EXPECT_EQ(r.resets, 0u);
}

// The same with the payload's friction inside its force balance (force_loop in mass_spring's place,
// friction_hysteresis still in series): the filter carries force_loop's y and v, its friction
// follows the filter's mean; 100 s, bounded, following, no reset.
TEST(OutputDynamics, TheFilterFollowsAModelWithFrictionInsideTheForceBalance) {
  const auto pc =
      plant::PlantConfig::fromJson(nlohmann::json::parse(R"({"kind":"model","effects":{"mass_spring":{"enabled":false},
      "force_loop":{"enabled":true,"fn":6.0,"zeta":0.4,"zmax":0.6,"delta":0.3}}})"),
                                   "test");
  ASSERT_TRUE(pc.truth.hasEffect("force_loop"));
  ASSERT_EQ(pc.truth.numFilterStates(), 2);
  const auto r = followThePlant(pc, 100'000);
  std::printf("emulator model with force_loop, 100 s: estimate RMSE %.4f mm (max %.3f mm), largest P_h %.3g\n", r.rmse,
              r.max_err, r.max_ph);
  EXPECT_LT(r.rmse, 0.05);
  EXPECT_LT(r.max_err, 0.5);
  EXPECT_LT(r.max_ph, 100.0);
  EXPECT_EQ(r.resets, 0u);
}

// The paper's Q (eq. 26, 10 per sample) with such a model: much noisier (the filter believes h may
// jump by 3 V per millisecond and can see it only through the mass-spring), but bounded, and the
// estimate stays inside the divergence guard's bound: no reset.
TEST(OutputDynamics, ThePapersProcessNoiseIsNoisierButStaysBounded) {
  const auto pc = plant::PlantConfig::modelDefaults();
  plant::Plant plant(pc);
  estimation::ActiveModelSettings s;
  s.Q_h_lag = s.Q_h;
  s.Q_f_lag = s.Q_f;
  estimation::ActiveModel am;
  am.configure(pc.truth, s, kTs);
  plant.reset(command(0));
  am.reset(command(0));
  double max_ph = 0.0, max_err = 0.0;
  for (long k = 0; k < 100'000; ++k) {
    const double u = command(k);
    const double y_true = plant.step(u);
    const auto st = am.update(u, plant.measure());
    ASSERT_NE(st.status, estimation::UkfStatus::Reset) << "sample " << k;
    if (k < 2000) continue;
    max_err = std::max(max_err, std::fabs(st.y_post - y_true));
    max_ph = std::max(max_ph, am.covariance()(0, 0));
  }
  std::printf("whole emulator model with eq. (26)'s Q: largest estimate error %.3f mm, largest P_h %.3g\n", max_err,
              max_ph);
  EXPECT_LT(max_err, s.diverge);
  EXPECT_LT(max_ph, 1e4);
  EXPECT_TRUE(spd(am.covariance()));
}

// A position the model cannot produce at all (its saturation levels off at knee + width = 36 mm, the
// sensor says 60 mm, within its range): the gate holds the first gate_max_rejects, then the filter takes
// it, and its posterior still misses by more than `diverge`: the guard restarts it and reports a reset
// (the controller node then goes to its safe state with EMCY 0x6100). Never a silent run-off.
TEST(OutputDynamics, TheDivergenceGuardRestartsAFilterThatCannotFollow) {
  const auto pc = plant::PlantConfig::modelDefaults();
  plant::Plant plant(pc);
  estimation::ActiveModel am;
  estimation::ActiveModelSettings on;
  on.Q_d = 0.0;  // h, f_h and the output states in the filter: its error on the position follows any level
  am.configure(pc.truth, on, kTs);
  plant.reset(command(0));
  am.reset(command(0));
  long k = 0;
  for (; k < 3000; ++k) {
    const double u = command(k);
    plant.step(u);
    ASSERT_NE(am.update(u, plant.measure()).status, estimation::UkfStatus::Reset);
  }
  EXPECT_EQ(am.divergences(), 0u);
  long first_reset = -1;
  for (long j = 0; j < 100; ++j, ++k) {
    const auto st = am.update(command(k), 60.0);
    EXPECT_TRUE(std::isfinite(st.y_post));
    EXPECT_TRUE(spd(am.covariance()));
    if (st.status == estimation::UkfStatus::Reset && first_reset < 0) first_reset = j;
  }
  EXPECT_GE(first_reset, 0) << "the filter never said it was lost";
  EXPECT_LE(first_reset, estimation::ActiveModelSettings{}.gate_max_rejects + 1);
  EXPECT_GE(am.divergences(), 1u);
  // With the guard off the same filter stays lost without a word.
  estimation::ActiveModelSettings off = on;
  off.diverge = 0.0;
  estimation::ActiveModel quiet;
  quiet.configure(pc.truth, off, kTs);
  quiet.reset(command(0));
  plant.reset(command(0));
  for (long j = 0; j < 3000; ++j) {
    plant.step(command(j));
    quiet.update(command(j), plant.measure());
  }
  double miss = 0.0;
  for (long j = 0; j < 100; ++j) miss = std::max(miss, std::fabs(60.0 - quiet.update(command(3000 + j), 60.0).y_post));
  EXPECT_GT(miss, estimation::ActiveModelSettings{}.diverge);
  EXPECT_EQ(quiet.divergences(), 0u);
}
