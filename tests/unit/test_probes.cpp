// Probes on data whose missing physics is not in the catalogue. The data are made here, by the core
// model and a transformation written out in this file (not by the probes' or effects' code), with
// other parameters and excitations than the emulator's defaults.
#include <gtest/gtest.h>

#include <filesystem>

#include <algorithm>
#include <string>

#include <cmath>
#include <cstdio>
#include <random>

#include "control/trajectory.hpp"
#include "diagnose/diagnose.hpp"
#include "io/model_file.hpp"
#include "model/model.hpp"
#include "model/probe.hpp"
#include "emulator_data.hpp"

using namespace pamc;

namespace {

const model::BoucWenParams kCore{5.0, 0.7, 16.0, 1.0, 0.4, 0.2};

// Core output on a random ramp-hold input, then `post(t, u, y)`, sensor noise 0.005 rms.
io::Measurement make(std::uint64_t seed, double seconds, double (*pre)(double), double (*post)(double, double)) {
  const auto traj = control::Trajectory::randomRampHold(seed, -2.5, 2.5);
  io::Measurement d;
  d.source = "probe data seed " + std::to_string(seed);
  d.Ts = 1e-3;
  const auto n = static_cast<size_t>(seconds / d.Ts);
  std::vector<double> ue(n);
  for (size_t i = 0; i < n; ++i) {
    d.t.push_back(static_cast<double>(i) * d.Ts);
    d.u.push_back(traj.at(d.t.back()));
    ue[i] = pre(d.u.back());
  }
  d.y = model::Model(kCore).simulate(ue, d.Ts);
  std::mt19937_64 rng(seed + 7);
  std::normal_distribution<double> noise(0.0, 0.005);
  for (size_t i = 0; i < n; ++i) d.y[i] = post(d.t[i], d.y[i]) + noise(rng);
  return d;
}

double same(double u) { return u; }

std::string table(const diagnose::DiagnoseResult& r) {
  std::string s = r.verdict + "\nprobes:";
  for (const auto& p : r.probes)
    s += "\n  " + p.label() + " " + std::to_string(p.rmse_val) + " " + std::to_string(p.explains);
  return s;
}
double sameOut(double, double y) { return y; }

diagnose::DiagnoseResult run(double (*pre)(double), double (*post)(double, double),
                             std::vector<std::string> cands = {}) {
  const auto train = make(11, 24.0, pre, post), val = make(12, 16.0, pre, post);
  diagnose::DiagnoseSettings s;
  s.method = ident::FitMethod::MultiStart;
  s.candidates = std::move(cands);
  auto r = diagnose::diagnose(train, &val, s);
  // The numbers of docs/MODELING.md's probe table: where the catalogue ends, the best probe.
  std::string fin;
  for (const auto& e : r.ladder.back().effects) fin += " + " + e;
  std::printf("catalogue ends at reference model%s, validated %.3g; best probe %s explains %.0f %% -> %.3g\n",
              fin.c_str(), r.ladder.back().rmse_val, r.probes.empty() ? "(none run)" : r.probes.front().probe.c_str(),
              r.probes.empty() ? 0.0 : 100 * r.probes.front().explains,
              r.probes.empty() ? 0.0 : r.probes.front().rmse_val);
  return r;
}

}  // namespace

// The rubber warms after the start and the muscle's travel grows with it: a gain that changes with
// time. With the catalogue as it was before warm_up (docs/MODELING.md) no effect is a function of time;
// the drift probe is.
TEST(Probes, AGainThatGrowsWithTimePointsAtDrift) {
  const auto r =
      run(same,
          [](double t, double y) {
            return 16.0 + (y - 16.0) * (1.0 + 0.12 * (1.0 - std::exp(-t / 6.0))) + 0.3 * (1.0 - std::exp(-t / 6.0));
          },
          {"-warm_up"});
  ASSERT_FALSE(r.probes.empty()) << table(r);
  EXPECT_EQ(r.probes.front().probe, "drift") << table(r);
  EXPECT_GT(r.probes.front().explains, 0.5) << table(r);
  EXPECT_TRUE(r.probe_rung);
  EXPECT_NE(r.verdict.find("drift"), std::string::npos) << table(r);
  EXPECT_NE(r.verdict.find("temperature"), std::string::npos) << table(r);
  // The probe that is a rung is offered as a ready model, which reads back with the probe in it.
  const auto dir = (std::filesystem::temp_directory_path() / "pamc_probe_report").string();
  const auto train = make(11, 24.0, same, sameOut);
  diagnose::writeReport(r, train, nullptr, diagnose::DiagnoseSettings{}, dir);
  const auto m = io::readModelFile(dir + "/probe_model.json");
  bool has = false;
  for (int i = 0; i < m.numEffects(); ++i) has = has || std::string(m.effect(i).name()) == "drift";
  EXPECT_TRUE(has);
}

// A valve whose pressure gain grows towards the ends of the command range: a curve on the input side.
TEST(Probes, ACurvedValveCharacteristicPointsAtTheInputCurve) {
  const auto r = run([](double u) { return u * (0.6 + 0.4 * (u / 2.5) * (u / 2.5)); }, sameOut);
  ASSERT_FALSE(r.probes.empty()) << table(r);
  EXPECT_EQ(r.probes.front().probe, "input_curve") << table(r);
  EXPECT_GT(r.probes.front().explains, 0.5) << table(r);
}

// A displacement sensor whose gain grows along its range (a saturating stroke would be the catalogue's
// saturation effect): a curve on the output side.
TEST(Probes, ACurvedSensorPointsAtTheOutputCurve) {
  const auto r = run(same, [](double, double y) { return y + 0.01 * (y - 16.0) * (y - 16.0); });
  ASSERT_FALSE(r.probes.empty()) << table(r);
  EXPECT_EQ(r.probes.front().probe, "output_curve") << table(r);
  EXPECT_GT(r.probes.front().explains, 0.5) << table(r);
}

// Reference-model data: the catalogue has nothing to add, and no probe explains noise.
TEST(Probes, NothingToExplainOnReferenceModelData) {
  const auto r = run(same, sameOut);
  EXPECT_EQ(r.ladder.size(), 1u) << table(r);
  EXPECT_FALSE(r.probe_rung) << table(r);
}

TEST(Probes, JsonContractAndNames) {
  const auto r = run(same, [](double t, double y) { return y + 0.5 * (1.0 - std::exp(-t / 5.0)); }, {"delay", "creep"});
  const auto j = diagnose::toJson(r);
  ASSERT_TRUE(j["probes"].is_array());
  // Every probe on top of the final model, and those that may stand for one of its effects in its place.
  ASSERT_GE(j["probes"].size(), model::probes().size());
  double last = 0;
  for (const auto& p : j["probes"]) {
    ASSERT_TRUE(p["probe"].is_string());
    EXPECT_NE(model::findProbe(p["probe"].get<std::string>()), nullptr);
    EXPECT_GE(p["rmse_val"].get<double>(), last);  // best first
    last = p["rmse_val"].get<double>();
    EXPECT_GE(p["explains"].get<double>(), 0.0);
    EXPECT_LE(p["explains"].get<double>(), 1.0);
    EXPECT_TRUE(p["regime"].is_string());
    EXPECT_FALSE(p["meaning"].get<std::string>().empty());
    // Twice as many when fitted with separate parameters rising and falling.
    EXPECT_EQ(p["params"].size(),
              (p.contains("direction") ? 2 : 1) * model::makeEffect(p["probe"].get<std::string>())->params().size());
    if (p.contains("replaces")) {
      const auto& fin = r.ladder.back().effects;
      EXPECT_NE(std::find(fin.begin(), fin.end(), p["replaces"].get<std::string>()), fin.end());
      EXPECT_TRUE(model::findProbe(p["probe"].get<std::string>())->standsFor(p["replaces"].get<std::string>()));
    }
  }
  // The ladder marks the probe's rung; the model holds physical effects only.
  const auto& last_rung = j["ladder"].back();
  ASSERT_TRUE(last_rung["probe"].get<bool>()) << table(r);  // the next line reads the probe's rung
  EXPECT_EQ(last_rung["effects"].back(), j["probes"][0]["probe"]);
  for (const auto& e : j["model"]["effects"]) EXPECT_EQ(model::findProbe(e["name"].get<std::string>()), nullptr);
}

// The second column of probes.inc names catalogue effects only (not probes, not unknown names).
TEST(Probes, StandForCatalogueEffectsOnly) {
  int standing = 0;
  for (const auto& p : model::probes()) {
    std::string list = p.stands_for;
    for (size_t at = 0; !list.empty(); list = at == std::string::npos ? "" : list.substr(at + 1)) {
      at = list.find(',');
      const std::string e = list.substr(0, at);
      EXPECT_EQ(model::findProbe(e), nullptr) << p.name << " stands for a probe: " << e;
      EXPECT_NO_THROW(model::makeEffect(e)) << p.name << " stands for an unknown effect: " << e;
      EXPECT_TRUE(p.standsFor(e));
      ++standing;
    }
  }
  EXPECT_GT(standing, 0);
  EXPECT_FALSE(model::findProbe("dead_zone")->standsFor(""));
  EXPECT_FALSE(model::findProbe("dead_zone")->standsFor("dead"));
}

// A regulator whose gain falls to half above 0.8 V (data made here): the catalogue stands in for the knee
// with what it has, and the piecewise-linear gain probe - on top of the final model or in the place of the
// effect that took the knee - names it and brings the validated error down at least 5x.
TEST(Probes, AKneeInTheCommandGainIsNamedByThePiecewiseGain) {
  const auto r = run([](double u) { return u <= 0.8 ? u : 0.8 + 0.5 * (u - 0.8); }, sameOut);
  ASSERT_FALSE(r.probes.empty()) << r.verdict;
  EXPECT_EQ(r.probes.front().probe, "piecewise_gain") << table(r);
  EXPECT_LE(5.0 * r.probes.front().rmse_val, r.ladder.back().rmse_val) << table(r);
}

// Every probe driven by the command or the displacement has a direction-dependent version ("<name>_updown",
// diagnose tries it for the top probe): with both parameter sets equal it is the probe itself.
TEST(Probes, DirectionDependentVersionsAreTheProbeWithEqualSets) {
  int versions = 0;
  for (const auto& e : model::probes()) {
    if (!e.make()->directional()) continue;
    ++versions;
    model::Model plain(kCore), both(kCore);
    plain.addEffect(e.name);
    const std::string updown = std::string(e.name) + model::kDirectionalSuffix;
    both.addEffect(updown);
    const auto& specs = e.make()->params();
    for (const auto& p : specs) {
      const double v = p.lo + 0.37 * (p.hi - p.lo);
      plain.setEffectParam(e.name, p.name, v);
      both.setEffectParam(updown, p.name + "_up", v);
      both.setEffectParam(updown, p.name + "_down", v);
    }
    std::vector<double> u(3000);
    for (size_t k = 0; k < u.size(); ++k) u[k] = 2.0 * std::sin(2 * M_PI * 0.7 * static_cast<double>(k) * 1e-3);
    const auto a = plain.simulate(u, 1e-3), b = both.simulate(u, 1e-3);
    for (size_t k = 0; k < u.size(); ++k) ASSERT_NEAR(a[k], b[k], 1e-12) << e.name << " at " << k;
  }
  EXPECT_GE(versions, 10);
  for (const char* none : {"drift", "periodic", "direction_lag"})
    EXPECT_FALSE(model::findProbe(none)->make()->directional()) << none;
}

TEST(Probes, AreNotCandidatesAndCanBeLeftOut) {
  const auto d = make(13, 6.0, same, sameOut);
  diagnose::DiagnoseSettings s;
  s.candidates = {"drift"};
  EXPECT_THROW(
      {
        try {
          diagnose::diagnose(d, nullptr, s);
        } catch (const std::invalid_argument& e) {
          EXPECT_NE(std::string(e.what()).find("is a probe"), std::string::npos) << e.what();
          throw;
        }
      },
      std::invalid_argument);
  s.candidates = {"delay", "-creep"};
  EXPECT_THROW(diagnose::diagnose(d, nullptr, s), std::invalid_argument);
}

TEST(Probes, EveryProbeStaysFiniteOnHugeSteps) {
  for (const auto& e : model::probes()) {
    model::Model m(kCore);
    m.addEffect(e.name);
    std::vector<double> u(5000);
    for (size_t i = 0; i < u.size(); ++i) u[i] = (i / 500 % 2 ? 1e3 : -1e3) * std::sin(0.01 * static_cast<double>(i));
    for (double y : m.simulate(u, 1e-3)) ASSERT_TRUE(std::isfinite(y)) << e.name;
  }
}

// The Prandtl-Ishlinskii probe: six plays with radii radius / 6, 2 radius / 6, ..., radius, each weight
// on its play's lag behind the command (written out here as a play operator of its own).
TEST(Probes, ThePlayProbeIsASumOfPlaysWithEvenlySpreadRadii) {
  const auto e = model::makeEffect("play_hysteresis");
  ASSERT_EQ(e->params().size(), 7u);
  double p[7] = {3.0, 0, 1.0, 0, 0, 0, 0.5};  // radii 0.5, 1, ..., 3: weight 1 on 1.0, 0.5 on 3.0
  std::vector<double> s(static_cast<size_t>(e->numStates()));
  model::StepContext c;
  c.u_eff = 0.0;
  e->init(p, s.data(), 0.0, c);
  double play1 = 0.0, play3 = 0.0;  // the plays of radius 1 and 3, from rest at 0
  for (const double u : {0.3, 1.0, 2.5, 1.2, 0.2, -1.5, 0.0}) {
    play1 = std::clamp(play1, u - 1.0, u + 1.0);
    play3 = std::clamp(play3, u - 3.0, u + 3.0);
    c.u_eff = u;
    const double y = e->step(p, s.data(), 10.0, c);
    EXPECT_NEAR(y, 10.0 + (play1 - u) + 0.5 * (play3 - u), 1e-12) << u;
  }
}

namespace {

// The core read through 2 mm of backlash in the linkage to the sensor (the reading follows the
// displacement only once the play is taken up), written out here, sensor noise 0.005 rms.
io::Measurement throughBacklash(std::uint64_t seed, double seconds) {
  auto d = make(seed, seconds, same, sameOut);
  const auto clean = model::Model(kCore).simulate(d.u, d.Ts);
  constexpr double kHalfPlay = 1.0;
  double reading = clean.front();
  for (size_t i = 0; i < clean.size(); ++i) {
    reading = std::clamp(reading, clean[i] - kHalfPlay, clean[i] + kHalfPlay);
    d.y[i] += reading - clean[i];  // make's record is the clean output plus its noise
  }
  return d;
}

}  // namespace

// Backlash that the catalogue's Dahl friction takes to near the noise: at the noise, only the probes in
// the place of the final model's effects are fitted, and the backlash probe in friction_hysteresis's place
// is reported when it lowers the validated error by min_gain - said as "though at the noise". On these
// records a play of 0.4 or 1 mm is taken by the friction to 1.02x and 1.08x the noise: nothing is left to
// tell them apart by min_gain, and no probe is reported; at 2 mm the friction ends at 1.14x.
TEST(Probes, AtTheNoiseAProbeInTheEffectsPlaceIsStillTried) {
  const auto train = throughBacklash(11, 24.0), val = throughBacklash(12, 16.0);
  diagnose::DiagnoseSettings s;
  s.method = ident::FitMethod::MultiStart;
  const auto r = diagnose::diagnose(train, &val, s);
  const auto& fin = r.ladder.back();
  std::string effects;
  for (const auto& e : fin.effects) effects += " + " + e;
  std::printf("catalogue ends at reference model%s, validated %.4g; %s\n", effects.c_str(), fin.rmse_val,
              r.probes.empty() ? "no probe"
                               : (r.probes.front().label() + " " + std::to_string(r.probes.front().rmse_val)).c_str());
  ASSERT_LT(fin.rmse_val, 1.5 * 0.005) << r.verdict;  // the catalogue ends at the noise
  ASSERT_FALSE(r.probes.empty()) << r.verdict;
  EXPECT_EQ(r.probes.front().label(), "backlash for friction_hysteresis") << table(r);
  EXPECT_TRUE(r.probe_rung) << table(r);
  for (const auto& p : r.probes) EXPECT_FALSE(p.replaces.empty()) << p.label();  // none on top at the noise
  EXPECT_NE(
      r.verdict.find("Though at the noise, the probe backlash fits better still in the place of friction_hysteresis"),
      std::string::npos)
      << r.verdict;
}

// A record over the whole stroke of the physics plant (60 000 samples, screened at 250 Hz), where the
// ladder ends in pneumatic_balance: the pressure's fast dynamics under the screening record's 4 ms hold of
// the input. No probe fitted there could win the share a probe must win, and none is fitted
// (docs/MODELING.md, `probes_unresolved`), for one of the rule's two reasons - which one moves with where
// the search lands: at 0.291 mm validated the final structure itself, fitted there, validated far worse
// (0.397 mm); at 0.0744 mm (since the balance's box holds friction_hysteresis's) the final model's own
// output moves more on the screening record (0.0555 mm rms) than what is left of the training record
// (0.0538). With the rule undone the probes are fitted and this test fails (and takes 133 s instead of 86).
// The same run shows the refinement's rule for a form that absorbs others: muscle_balance, in force_loop's
// place, goes from its quick search to the refit, not to the GA over its whole box (docs/MODELING.md, "The
// GA's search of a richer form").
TEST(Probes, AreNotFittedWhereTheScreeningRecordCannotResolveTheFinalModel) {
  const auto physics = plant::PlantConfig::defaults();  // rig mode: every effect of the muscle at once
  const auto train = testdata::emulatorRecord(physics, 1, 60.0, false, -3.5, 4.0);  // random:1:-3.5:4
  const auto val = testdata::emulatorRecord(physics, 2, 30.0, false, -3.5, 4.0);
  diagnose::DiagnoseSettings s;
  std::string log;
  s.log = [&log](const std::string& line) { log += line + "\n"; };
  const auto r = diagnose::diagnose(train, &val, s);
  EXPECT_NE(log.find("force_loop as muscle_balance: validation"), std::string::npos) << log;
  EXPECT_EQ(log.find("GA: muscle_balance"), std::string::npos) << log;
  std::printf("%s\n%s\n", r.verdict.c_str(), r.probes_unresolved.c_str());
  ASSERT_FALSE(r.ladder.empty());
  ASSERT_TRUE(r.ladder.back().model.hasEffect("pneumatic_balance"))
      << "the premise: the ladder ends in the pressure's dynamics";
  const bool null_probe = r.probes_unresolved.find("the final model itself") != std::string::npos;
  const bool moves = r.probes_unresolved.find("the final model's own output moves") != std::string::npos;
  EXPECT_TRUE(null_probe || moves) << r.probes_unresolved;
  EXPECT_TRUE(r.probes.empty());
}
