// The modelling loop on data with hidden effects: emulator data from fixed seeds, different
// excitations for training and validation, the effect's parameters unknown to the diagnosis.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "diagnose/compare.hpp"
#include "diagnose/diagnose.hpp"
#include "diagnose/diagnosis.hpp"
#include "emulator_data.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {

// Plant with the plain Bouc-Wen core (k = 6) plus the listed effects (JSON fragments).
plant::PlantConfig hidden(const std::string& effects_json) {
  return testdata::plainPlantWith(R"({"k":6.0})", effects_json);
}

io::Measurement record(const plant::PlantConfig& pc, std::uint64_t seed, double seconds, bool with_load) {
  return testdata::emulatorRecord(pc, seed, seconds, with_load);
}

// Trained on seed 1, validated on seed 2 (the records of tools/hidden_effects.sh are 40 s and 30 s).
diagnose::DiagnoseResult run(const plant::PlantConfig& pc, bool with_load = false, double train_s = 24.0,
                             double val_s = 16.0) {
  const auto train = record(pc, 1, train_s, with_load);
  const auto val = record(pc, 2, val_s, with_load);
  diagnose::DiagnoseSettings s;
  s.seed = 1;
  return diagnose::diagnose(train, &val, s);
}

struct Hidden {
  const char* effect;
  const char* json;
};

}  // namespace

class HiddenEffect : public ::testing::TestWithParam<Hidden> {};

TEST_P(HiddenEffect, IsNamedFirstAndTheValidatedErrorFallsFiveFold) {
  const auto& h = GetParam();
  const auto r = run(hidden(h.json), std::string(h.effect) == "load");
  ASSERT_GE(r.ladder.size(), 2u) << r.verdict;
  EXPECT_EQ(r.ladder[1].effects.front(), h.effect) << r.verdict;
  EXPECT_EQ(r.rounds.front().front().effect, h.effect);
  EXPECT_GE(r.ladder.front().rmse_val / r.ladder.back().rmse_val, 5.0) << r.verdict;
  // The floor, and nothing spurious: the hidden effect alone, within 1.5x of the emulator's noise
  // (0.004 mm rms plus its 0.001 mm quantisation). Not for warm_up: the emulator's tube starts warming
  // when the plant is reset (at u = 0, a second before the record), the model's at the record's first
  // sample: the true parameters leave the records 0.07-0.1 mm off (15-20x the noise; `pamc compare`),
  // the true family does not reach the noise on them.
  EXPECT_EQ(r.ladder.back().effects, std::vector<std::string>{h.effect}) << r.verdict;
  const double noise = std::sqrt(0.004 * 0.004 + 0.001 * 0.001 / 12.0);
  if (std::string(h.effect) != "warm_up") {
    EXPECT_LT(r.ladder.back().rmse_val, 1.5 * noise) << r.verdict;
    EXPECT_EQ(r.verdict.find("start in different states"), std::string::npos) << r.verdict;
  }
}

INSTANTIATE_TEST_SUITE_P(
    Catalogue, HiddenEffect,
    ::testing::Values(Hidden{"pressure_lag", R"("pressure_lag":{"enabled":true,"tau":0.06,"slew":1000})"},
                      Hidden{"asymmetry", R"("asymmetry":{"enabled":true,"gain":2,"w_up":1.5,"w_down":0.3})"},
                      Hidden{"creep", R"("creep":{"enabled":true,"fraction":0.1,"tau":3})"},
                      Hidden{"mass_spring", R"("mass_spring":{"enabled":true,"fn":3,"zeta":0.3})"},
                      Hidden{"force_loop", R"("force_loop":{"enabled":true,"fn":3,"zeta":0.3,"zmax":1.0,"delta":0.5})"},
                      Hidden{"friction_hysteresis", R"("friction_hysteresis":{"enabled":true,"zmax":1.0,"delta":0.5})"},
                      Hidden{"delay", R"("delay":{"enabled":true,"d":0.03})"},
                      Hidden{"dead_band", R"("dead_band":{"enabled":true,"threshold":-1.0})"},
                      Hidden{"load", R"("load":{"enabled":true,"compliance":0.08})"},
                      Hidden{"saturation", R"("saturation":{"enabled":true,"knee":26,"width":6})"},
                      Hidden{"warm_up", R"("warm_up":{"enabled":true,"tau":7,"gain":0.12,"shift":0.4})"}),
    [](const auto& info) { return std::string(info.param.effect); });

// Pruning judges a removal that misses its bound by little on a refit over all the training samples,
// not on the screening fit alone. Hidden asymmetry on longer records (40 s / 30 s, as
// tools/hidden_effects.sh): the asymmetry's first fit ends in a wrong basin, a delay added on top
// helps it out (0.0040 mm), and without the delay the screening refit ends at 0.0054 mm (1.3x the
// noise, refused) where the refit on all samples is back at 0.0040: the delay must go again.
TEST(Diagnose, PruningRefitsARemovalThatMissesByLittle) {
  const auto r = run(hidden(R"("asymmetry":{"enabled":true,"gain":2,"w_up":1.5,"w_down":0.3})"), false, 40.0, 30.0);
  EXPECT_EQ(r.ladder.back().effects, std::vector<std::string>{"asymmetry"}) << r.verdict;
  const double noise = std::sqrt(0.004 * 0.004 + 0.001 * 0.001 / 12.0);
  EXPECT_LT(r.ladder.back().rmse_val, 1.5 * noise) << r.verdict;
}

// A model at the noise on its training record and off by a constant on the validation record: the
// records start in different states, and the verdict says so instead of "nothing systematic is left".
// Hidden warm-up on 40 s / 30 s records (as tools/hidden_effects.sh): the emulator's tube starts warming
// a second before each record, and the part already there is taken up by the core on the training
// record, at a level that differs on the validation record (docs/MODELING.md).
TEST(Diagnose, AnOffsetBetweenTheRecordsIsNamed) {
  const auto r = run(hidden(R"("warm_up":{"enabled":true,"tau":15,"gain":0.1,"shift":0.5})"), false, 40.0, 30.0);
  EXPECT_EQ(r.ladder.back().effects, std::vector<std::string>{"warm_up"}) << r.verdict;
  EXPECT_NEAR(r.val_offset, -0.186, 0.01) << r.verdict;
  EXPECT_NE(r.verdict.find("start in different states"), std::string::npos) << r.verdict;
  EXPECT_NE(r.verdict.find("without --validate"), std::string::npos) << r.verdict;  // a validation file was given
  EXPECT_EQ(r.verdict.find("nothing systematic is left"), std::string::npos) << r.verdict;
  EXPECT_NEAR(diagnose::toJson(r)["validation_offset"].get<double>(), r.val_offset, 1e-12);
  // There from the validation record's start on: not an offset that builds up.
  EXPECT_FALSE(r.val_offset_course.buildsUp()) << r.val_offset_course.head << " " << r.val_offset_course.tail;
  EXPECT_EQ(diagnose::toJson(r)["validation_offset_course"]["second_half"].get<double>(), r.val_offset_course.tail);
}

// An offset present from the record's first samples (records that start in different states) against one
// the model comes to over the record (it settles elsewhere than the muscle on the record's input: the paper's
// u0 -> u1 on the calibrated physics plant, docs/MODELING.md).
TEST(Diagnose, AnOffsetThatBuildsUpOverTheRecordIsToldFromOneAtItsStart) {
  const size_t n = 4000;
  std::vector<double> constant(n), rising(n), fading(n), turning(n), none(n);
  for (size_t i = 0; i < n; ++i) {
    const double t = static_cast<double>(i) / n, wiggle = 0.01 * std::sin(0.05 * static_cast<double>(i));
    constant[i] = -0.2 + wiggle;
    rising[i] = -0.04 * (1.0 - std::exp(-t / 0.15)) + wiggle;  // the model settling over the first half
    fading[i] = -0.2 * std::exp(-t / 0.3) - 0.05 + wiggle;     // a warm-up under way at the start
    turning[i] = t < 0.3 ? 0.03 : -0.04;                       // of the other sign at first
    none[i] = wiggle;
  }
  const auto c = diagnose::offsetCourse(constant.data(), n);
  EXPECT_NEAR(c.head, -0.2, 0.01);
  EXPECT_NEAR(c.tail, -0.2, 0.01);
  EXPECT_FALSE(c.buildsUp());
  const auto r = diagnose::offsetCourse(rising.data(), n);
  EXPECT_GT(r.head, 0.5 * r.tail);  // both negative: the first tenth's under half the second half's
  EXPECT_TRUE(r.buildsUp());
  EXPECT_FALSE(diagnose::offsetCourse(fading.data(), n).buildsUp());
  EXPECT_TRUE(diagnose::offsetCourse(turning.data(), n).buildsUp());
  EXPECT_FALSE(diagnose::offsetCourse(constant.data(), 10).buildsUp());  // too short to tell
  EXPECT_NEAR(diagnose::offsetCourse(none.data(), n).tail, 0.0, 0.01);
}

TEST(Diagnose, TwoHiddenEffectsAreBothAdded) {
  const auto r = run(hidden(
      R"("pressure_lag":{"enabled":true,"tau":0.06,"slew":1000},"creep":{"enabled":true,"fraction":0.08,"tau":4})"));
  const auto& fin = r.ladder.back().effects;
  EXPECT_NE(std::find(fin.begin(), fin.end(), "pressure_lag"), fin.end()) << r.verdict;
  EXPECT_NE(std::find(fin.begin(), fin.end(), "creep"), fin.end()) << r.verdict;
  EXPECT_GE(r.ladder.front().rmse_val / r.ladder.back().rmse_val, 5.0);
}

// A run cut short keeps what it reached: every rung is handed to the checkpoint as it is taken, with the
// range its models were fitted on, the last one as the run ends it; and handing them over changes nothing.
TEST(Diagnose, EveryRungIsHandedToTheCheckpointAsItIsReached) {
  const auto pc = hidden(R"("pressure_lag":{"enabled":true,"tau":0.06,"slew":1000})");
  const auto train = record(pc, 1, 24.0, false), val = record(pc, 2, 16.0, false);
  diagnose::DiagnoseSettings s;
  s.seed = 1;
  s.probes = false;
  const auto plain = diagnose::diagnose(train, &val, s);
  const auto trained = model::OperatingRange::of(train.u.data(), train.y.data(), train.size(), train.Ts);
  std::vector<std::string> after;
  std::vector<diagnose::Rung> last;
  std::vector<size_t> sizes;
  s.checkpoint = [&](const diagnose::DiagnoseResult& so_far, const std::string& step) {
    after.push_back(step);
    sizes.push_back(so_far.ladder.size());
    last = so_far.ladder;
    for (const auto& rung : so_far.ladder) {  // the training record's, as the final model's
      const auto& g = rung.model.range();
      EXPECT_TRUE(g.known) << step;
      EXPECT_EQ(g.rate.lo, trained.rate.lo) << step;
      EXPECT_EQ(g.rate.hi, trained.rate.hi) << step;
    }
  };
  const auto r = diagnose::diagnose(train, &val, s);
  ASSERT_GE(after.size(), 3u);
  EXPECT_EQ(after.front(), "the reference model");
  EXPECT_EQ(sizes.front(), 1u);
  EXPECT_NE(std::find(after.begin(), after.end(), "round 1"), after.end());
  EXPECT_TRUE(std::is_sorted(sizes.begin(), sizes.end()));
  ASSERT_EQ(last.size(), r.ladder.size());
  EXPECT_DOUBLE_EQ(last.back().rmse_val, r.ladder.back().rmse_val);
  ASSERT_EQ(plain.ladder.size(), r.ladder.size());
  for (size_t i = 0; i < r.ladder.size(); ++i) EXPECT_DOUBLE_EQ(plain.ladder[i].rmse_val, r.ladder[i].rmse_val) << i;
}

// Two hidden effects at once, with other parameters and other excitations (seeds 5 and 6) than the
// cases above: diagnose ends at the sensor noise (within 1.5x of the emulator's 0.004 mm rms plus its
// 0.001 mm quantisation) with exactly the two effects the data hold, nothing spurious left in.
struct Pair {
  const char* a;
  const char* b;
  const char* json;
};
class TwoHidden : public ::testing::TestWithParam<Pair> {};

TEST_P(TwoHidden, EndAtTheNoiseWithNothingSpurious) {
  const auto& h = GetParam();
  const auto pc = hidden(h.json);
  const auto train = record(pc, 5, 24.0, false), val = record(pc, 6, 16.0, false);
  diagnose::DiagnoseSettings s;
  s.seed = 3;
  const auto r = diagnose::diagnose(train, &val, s);
  auto fin = r.ladder.back().effects;
  std::sort(fin.begin(), fin.end());
  std::vector<std::string> want{h.a, h.b};
  std::sort(want.begin(), want.end());
  EXPECT_EQ(fin, want) << r.verdict;
  const double noise = std::sqrt(0.004 * 0.004 + 0.001 * 0.001 / 12.0);
  EXPECT_LT(r.ladder.back().rmse_val, 1.5 * noise) << r.verdict;
}

INSTANTIATE_TEST_SUITE_P(
    Pairs, TwoHidden,
    ::testing::Values(
        Pair{
            "pressure_lag", "creep",
            R"("pressure_lag":{"enabled":true,"tau":0.1,"slew":1000},"creep":{"enabled":true,"fraction":0.06,"tau":2})"},
        Pair{"dead_band", "mass_spring",
             R"("dead_band":{"enabled":true,"threshold":-0.8},"mass_spring":{"enabled":true,"fn":4,"zeta":0.4})"},
        Pair{"delay", "saturation",
             R"("delay":{"enabled":true,"d":0.02},"saturation":{"enabled":true,"knee":24,"width":5})"}),
    [](const auto& info) { return std::string(info.param.a) + "_" + info.param.b; });

TEST(Diagnose, ReferenceModelDataAddsNothing) {
  const auto r = run(hidden(""));
  EXPECT_EQ(r.ladder.size(), 1u) << r.verdict;
  EXPECT_NE(r.verdict.find("No effect"), std::string::npos);
  EXPECT_NE(r.verdict.find("nothing systematic is left"), std::string::npos) << r.verdict;
}

TEST(Diagnose, HoldsOutDataWithoutValidationFileAndKeepsTheJsonContract) {
  const auto d = record(hidden(R"("delay":{"enabled":true,"d":0.02})"), 3, 30.0, false);
  diagnose::DiagnoseSettings s;
  s.max_effects = 1;
  const auto r = diagnose::diagnose(d, nullptr, s);
  const auto j = diagnose::toJson(r);
  EXPECT_EQ(j["samples"].get<size_t>(), static_cast<size_t>(30000 * 0.7));
  ASSERT_TRUE(j["baseline"].is_object());
  EXPECT_TRUE(j["baseline"]["rmse_train"].is_number());
  EXPECT_TRUE(j["baseline"]["rmse_val"].is_number());
  ASSERT_TRUE(j["candidates"].is_array());
  ASSERT_FALSE(j["candidates"].empty());
  double last = 0;
  for (const auto& c : j["candidates"]) {
    EXPECT_TRUE(c["effect"].is_string());
    EXPECT_TRUE(c["evidence"].is_string());
    EXPECT_GE(c["rmse_val"].get<double>(), last);  // best first
    last = c["rmse_val"].get<double>();
  }
  ASSERT_TRUE(j["ladder"].is_array());
  EXPECT_TRUE(j["ladder"][0]["effects"].empty());
  EXPECT_EQ(j["ladder"][1]["effects"][0], "delay");
  EXPECT_EQ(j["model"]["format"], "pamc-model/1");
  EXPECT_EQ(j["model"]["effects"][0]["name"], "delay");
}

TEST(Compare, PerfectModelFitsAndDelayShowsInTheResidual) {
  model::Model m({6.0, 1.25, 18.0, 1.0, 0.35, 0.25});
  io::Measurement d;
  d.source = "x";
  d.Ts = 1e-3;
  const auto u = control::Trajectory::randomRampHold(4, -2.5, 2.5);
  for (int i = 0; i < 20000; ++i) {
    d.t.push_back(i * 1e-3);
    d.u.push_back(u.at(i * 1e-3));
  }
  d.y = m.simulate(d.u, d.Ts);
  auto c = diagnose::compare(m, d);
  EXPECT_NEAR(c.report.rmse, 0.0, 1e-12);
  EXPECT_NEAR(c.report.fit_pct, 100.0, 1e-9);
  // Data delayed by 25 ms against the undelayed model: the best alignment shift says so.
  model::Model delayed = m;
  delayed.addEffect("delay");
  delayed.setEffectParam("delay", "d", 0.025);
  d.y = delayed.simulate(d.u, d.Ts);
  c = diagnose::compare(m, d);
  EXPECT_NEAR(c.report.ind.at("best_shift_s"), 0.025, 0.003);
  EXPECT_LT(c.report.fit_pct, 99.0);
  EXPECT_GT(c.report.acf[1], c.report.conf);  // residual not white
}

// The screening's step in the log: "every 3rd training sample", not "3th".
TEST(Diagnose, TheScreeningsStepIsAnOrdinal) {
  const std::pair<size_t, const char*> cases[] = {{1, "1st"},   {2, "2nd"},   {3, "3rd"},    {4, "4th"},
                                                  {11, "11th"}, {12, "12th"}, {13, "13th"},  {21, "21st"},
                                                  {22, "22nd"}, {23, "23rd"}, {111, "111th"}};
  for (const auto& [n, want] : cases) EXPECT_EQ(diagnose::detail::ordinal(n), want);
}
