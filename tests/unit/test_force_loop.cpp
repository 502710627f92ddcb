// force_loop: the payload's force balance with friction inside it (m y'' + c y' + k y + z(y') = F).
// Its limits (no friction: mass_spring), its quasi-static loop (2 zmax wide), its bounds under
// hard inputs, its identification, and diagnose naming it on data made with that structure.
#include <gtest/gtest.h>

#include "emulator_data.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "diagnose/diagnose.hpp"
#include "ident/identify.hpp"
#include "model/model.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {

constexpr double kTs = 1e-3;

// y = force_loop(in) alone: a core with rho = 1, k = 1, b = 0 passes the input through.
model::Model loopOnly(double fn, double zeta, double zmax, double delta) {
  model::Model m({1.0, 1.0, 0.0, 1.0, 0.3, 0.3});
  m.addEffect("force_loop");
  m.setEffectParam("force_loop", "fn", fn);
  m.setEffectParam("force_loop", "zeta", zeta);
  m.setEffectParam("force_loop", "zmax", zmax);
  m.setEffectParam("force_loop", "delta", delta);
  return m;
}

// Plant: the Bouc-Wen core given plus the listed effects (JSON fragments), every other effect off,
// noise and quantisation on, as in test_diagnose.cpp.
plant::PlantConfig plantWith(const std::string& core_json, const std::string& effects_json) {
  return testdata::plainPlantWith(core_json, effects_json);
}

io::Measurement record(const plant::PlantConfig& pc, std::uint64_t seed, double seconds) {
  return testdata::emulatorRecord(pc, seed, seconds);
}

double paramOf(const model::Model& m, const std::string& name) {
  const auto specs = m.paramSpecs();
  const auto p = m.params();
  for (size_t i = 0; i < specs.size(); ++i)
    if (specs[i].name == name) return p[i];
  ADD_FAILURE() << "no parameter " << name;
  return NAN;
}

}  // namespace

TEST(ForceLoop, WithoutFrictionItIsMassSpring) {
  for (double fn : {0.7, 6.0, 45.0, 100.0}) {
    model::Model fl = loopOnly(fn, 0.3, 0.0, 0.5);
    model::Model ms({1.0, 1.0, 0.0, 1.0, 0.3, 0.3});
    ms.addEffect("mass_spring");
    ms.setEffectParam("mass_spring", "fn", fn);
    ms.setEffectParam("mass_spring", "zeta", 0.3);
    std::vector<double> u(20000);
    for (size_t k = 0; k < u.size(); ++k)
      u[k] = 20.0 * std::sin(2 * M_PI * 0.7 * static_cast<double>(k) * kTs) + (k % 4000 < 2000 ? 5.0 : -5.0);
    const auto a = fl.simulate(u, kTs), b = ms.simulate(u, kTs);
    double worst = 0.0;
    for (size_t k = 0; k < u.size(); ++k) worst = std::max(worst, std::fabs(a[k] - b[k]));
    EXPECT_LT(worst, 1e-9) << "fn " << fn;
  }
}

TEST(ForceLoop, IsAnAlternativeToMassSpring) {
  model::Model m;
  m.addEffect("mass_spring");
  EXPECT_THROW(m.addEffect("force_loop"), std::invalid_argument);
  EXPECT_EQ(m.describe(), "bouc_wen + mass_spring");  // the refused effect left no trace
  model::Model f;
  f.addEffect("force_loop");
  EXPECT_THROW(f.addEffect("mass_spring"), std::invalid_argument);
  f.addEffect("creep");  // 2 + 1 filter states: fits
  EXPECT_EQ(f.numFilterStates(), 3);
  f.addEffect("friction_hysteresis");
  EXPECT_EQ(f.describe(), "bouc_wen + creep + friction_hysteresis + force_loop");
}

// The emulator switches it on from JSON like every effect; next to mass_spring it says why not.
TEST(ForceLoop, TheEmulatorTakesItFromJson) {
  const auto pc = plantWith(R"({"k":6.0})", R"("force_loop":{"enabled":true,"fn":7.0,"zmax":0.4})");
  ASSERT_TRUE(pc.truth.hasEffect("force_loop"));
  EXPECT_DOUBLE_EQ(paramOf(pc.truth, "force_loop.fn"), 7.0);
  EXPECT_DOUBLE_EQ(paramOf(pc.truth, "force_loop.zmax"), 0.4);
  EXPECT_DOUBLE_EQ(paramOf(pc.truth, "force_loop.zeta"), 0.5);  // the default
  const auto back = plant::PlantConfig::fromJson(pc.toJson(), "round trip");
  EXPECT_EQ(back.truth.params(), pc.truth.params());
  try {
    // The default emulator has mass_spring on.
    plant::PlantConfig::fromJson(nlohmann::json::parse(R"({"kind":"model","effects":{"force_loop":{"enabled":true}}})"),
                                 "cfg.json");
    ADD_FAILURE() << "force_loop next to mass_spring was taken";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cfg.json: effects"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("alternatives"), std::string::npos) << e.what();
  }
}

// A slow sine of the force: the displacement lags the force by the friction at every reversal, so
// y against in is a loop 2 zmax wide (in the force direction) at the middle of the stroke.
TEST(ForceLoop, QuasiStaticLoopIsTwiceTheFrictionWide) {
  for (double zmax : {0.3, 1.0, 2.5}) {
    model::Model m = loopOnly(20.0, 0.7, zmax, 0.05);
    const int n = 100000;  // 0.02 Hz, two periods
    std::vector<double> u(static_cast<size_t>(n));
    for (int k = 0; k < n; ++k) u[static_cast<size_t>(k)] = 10.0 * std::sin(2 * M_PI * 0.02 * k * kTs);
    const auto y = m.simulate(u, kTs);
    // Second period: in - y on the rising and on the falling branch where y passes 0.
    double up = NAN, down = NAN;
    for (int k = n / 2 + 1; k < n; ++k) {
      const auto i = static_cast<size_t>(k);
      if (y[i - 1] < 0.0 && y[i] >= 0.0) up = u[i];
      if (y[i - 1] > 0.0 && y[i] <= 0.0) down = u[i];
    }
    ASSERT_TRUE(std::isfinite(up) && std::isfinite(down)) << zmax;
    const double width = up - down;
    // Friction on both branches plus the viscous force at the crossing's speed on both.
    const double viscous = 2.0 * 0.7 / (2 * M_PI * 20.0) * 10.0 * 2 * M_PI * 0.02;
    std::printf("zmax %.2f: loop width %.4f (2 zmax + viscous = %.4f)\n", zmax, width, 2 * zmax + 2 * viscous);
    EXPECT_NEAR(width, 2.0 * zmax + 2.0 * viscous, 0.02 * 2.0 * zmax) << zmax;
  }
}

TEST(ForceLoop, StaysBoundedUnderStepsAndAHugeRange) {
  for (double fn : {0.2, 10.0, 100.0})
    for (double delta : {1e-4, 0.5, 20.0}) {
      model::Model m = loopOnly(fn, 0.01, 5.0, delta);
      std::vector<double> u(30000);
      for (size_t k = 0; k < u.size(); ++k) u[k] = (k / 500) % 2 ? 1e3 : -1e3;  // 1 Hz square, 2e3 swing
      const auto y = m.simulate(u, kTs);
      double peak = 0.0;
      for (double v : y) {
        ASSERT_TRUE(std::isfinite(v)) << fn << " " << delta;
        peak = std::max(peak, std::fabs(v));
      }
      // Underdamped overshoot at most doubles a step; friction only takes from it.
      EXPECT_LT(peak, 3.0 * 1e3) << fn << " " << delta;
    }
}

// Data made with core + force_loop (emulator noise and quantisation): a fit of that structure
// recovers the validated error near the noise and the loop's parameters.
TEST(ForceLoop, IdentificationRecoversTheLoop) {
  const auto pc = plantWith(R"({"k":5.0,"rho":0.9,"b":15.0,"beta":0.3,"gamma":0.2})",
                            R"("force_loop":{"enabled":true,"fn":4.0,"zeta":0.25,"zmax":0.8,"delta":0.3})");
  const auto train = record(pc, 11, 16.0);
  const auto val = record(pc, 12, 12.0);
  model::Model structure;
  structure.addEffect("force_loop");
  ident::FitSettings s = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  s.ga.seed = 7;
  const auto f = ident::fit(structure, train, s);
  const double rv = ident::rmseFrom(f.model, val);
  const double fn = paramOf(f.model, "force_loop.fn"), zeta = paramOf(f.model, "force_loop.zeta"),
               zmax = paramOf(f.model, "force_loop.zmax"), delta = paramOf(f.model, "force_loop.delta");
  std::printf("fit: rmse train %.5f val %.5f (noise 0.004), fn %.3f zeta %.3f zmax %.3f delta %.3f (%.1f s)\n", f.rmse,
              rv, fn, zeta, zmax, delta, f.seconds);
  EXPECT_LT(rv, 2.0 * 0.004);
  EXPECT_NEAR(fn, 4.0, 0.1);
  EXPECT_NEAR(zeta, 0.25, 0.02);
  EXPECT_NEAR(zmax, 0.8, 0.05);
  EXPECT_NEAR(delta, 0.3, 0.05);
}

// Data made with the hysteresis mainly inside the force balance (a core with little loop of its own,
// friction in the payload's force balance): diagnose names force_loop first, and the validated error
// it reaches is well below what the best series chain (the same catalogue without force_loop) reaches.
TEST(ForceLoopDiagnose, IsNamedFirstAndBeatsTheSeriesChain) {
  const auto pc = plantWith(R"({"k":6.0,"rho":0.97,"b":18.0,"beta":0.35,"gamma":0.25})",
                            R"("force_loop":{"enabled":true,"fn":3.0,"zeta":0.3,"zmax":1.0,"delta":0.5})");
  const auto train = record(pc, 1, 12.0);
  const auto val = record(pc, 2, 8.0);
  diagnose::DiagnoseSettings s;
  s.seed = 1;
  const auto r = diagnose::diagnose(train, &val, s);
  std::printf("with force_loop: %s\n", r.verdict.c_str());
  for (const auto& c : r.rounds.front()) std::printf("  round 1: %-20s val %.5f\n", c.effect.c_str(), c.rmse_val);
  ASSERT_GE(r.ladder.size(), 2u) << r.verdict;
  EXPECT_EQ(r.ladder[1].effects.front(), "force_loop") << r.verdict;

  EXPECT_LT(r.ladder.back().rmse_val, 2.0 * 0.004) << r.verdict;

  // The series chain, fitted as one: the branches' asymmetry on the command, the core, friction
  // driven by the output's motion, then the payload's inertia (mass_spring + asymmetry, as diagnose
  // ends without force_loop, plus friction_hysteresis), started from diagnose's mass_spring candidate;
  // the better of the two counts.
  const diagnose::CandidateResult* ms = nullptr;
  for (const auto& c : r.rounds.front())
    if (c.effect == "mass_spring") ms = &c;
  ASSERT_NE(ms, nullptr);
  model::Model chain = ms->model;
  for (const char* e : {"asymmetry", "friction_hysteresis"}) chain.addEffect(e);
  ident::FitSettings fs = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  fs.ga.seed = 3;
  const auto fc = ident::fit(chain, train, fs, {}, &ms->model);
  const double chain_val = std::min(ident::rmseFrom(fc.model, val), ms->rmse_val);
  const double ratio = chain_val / r.ladder.back().rmse_val;
  std::printf("validated RMSE: series chain %.5f (%s), with force_loop %.5f: ratio %.1f (%.1f s + %.1f s)\n", chain_val,
              fc.model.describe().c_str(), r.ladder.back().rmse_val, ratio, r.seconds, fc.seconds);
  EXPECT_GE(ratio, 20.0);
}
