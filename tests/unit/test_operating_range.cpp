// A model knows where it holds: the range of the record it was identified on, in its file, in compare and
// in the control loop.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "control/controller.hpp"
#include "diagnose/compare.hpp"
#include "ident/identify.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "model/operating_range.hpp"
#include "nodes/range_watch.hpp"
#include "plant/plant.hpp"

using namespace pamc;

namespace {

// u a ramp from -1 to 2 V over 3 s, then a jump back to 0; y = 10 + 5 u.
io::Measurement rampRecord() {
  io::Measurement d;
  d.source = "ramp.csv";
  d.Ts = 0.01;
  for (int i = 0; i <= 300; ++i) {
    d.t.push_back(i * d.Ts);
    d.u.push_back(-1.0 + 0.01 * i);
    d.y.push_back(10.0 + 5.0 * d.u.back());
  }
  d.t.push_back(301 * d.Ts);
  d.u.push_back(0.0);
  d.y.push_back(10.0);
  return d;
}

std::string modelError(const nlohmann::json& range) {
  auto j = io::modelToJson(model::Model({6.5, 1.2, 17.0, 1.0, 0.3, 0.2}));
  j["range"] = range;
  try {
    io::modelFromJson(j, "m.json");
  } catch (const io::InputError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

TEST(OperatingRange, IsTheRecordsRangeOfInputOutputAndInputRate) {
  const auto d = rampRecord();
  const auto r = model::OperatingRange::of(d.u.data(), d.y.data(), d.size(), d.Ts);
  ASSERT_TRUE(r.known);
  EXPECT_DOUBLE_EQ(r.input.lo, -1.0);
  EXPECT_NEAR(r.input.hi, 2.0, 1e-12);
  EXPECT_DOUBLE_EQ(r.output.lo, 5.0);
  EXPECT_NEAR(r.output.hi, 20.0, 1e-12);
  EXPECT_NEAR(r.rate.hi, 1.0, 1e-9);     // the ramp: 0.01 V per 10 ms
  EXPECT_NEAR(r.rate.lo, -200.0, 1e-9);  // the jump from 2 V to 0 in one sample
  EXPECT_EQ(r.check(0.5, 12.0, 0.0), model::RangeExcess::None);
  EXPECT_EQ(r.check(2.5, 12.0, 0.0), model::RangeExcess::InputHigh);
  EXPECT_EQ(r.check(0.5, 4.0, 0.0), model::RangeExcess::OutputLow);
  EXPECT_EQ(r.check(0.5, 12.0, 5.0), model::RangeExcess::RateHigh);
  EXPECT_EQ(model::OperatingRange{}.check(1e9, 1e9, 1e9), model::RangeExcess::None);  // unknown: holds everywhere
}

TEST(OperatingRange, AFittedModelRecordsItAndItsFileKeepsIt) {
  const auto d = rampRecord();
  auto s = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  s.lm_spread_starts = 1;
  s.lm_iterations = 2;
  s.refine = false;
  const auto f = ident::fit(model::Model{}, d, s);
  ASSERT_TRUE(f.model.range().known);
  EXPECT_DOUBLE_EQ(f.model.range().output.lo, 5.0);
  const std::string path = ::testing::TempDir() + "/pamc_range_model.json";
  io::writeModelFile(path, f.model);
  const auto back = io::readModelFile(path);
  ASSERT_TRUE(back.range().known);
  EXPECT_DOUBLE_EQ(back.range().rate.lo, f.model.range().rate.lo);
  EXPECT_DOUBLE_EQ(back.range().output.hi, f.model.range().output.hi);
  // A file from before ranges were recorded still loads, with none.
  auto j = io::modelToJson(f.model);
  ASSERT_TRUE(j.contains("range"));
  j.erase("range");
  EXPECT_FALSE(io::modelFromJson(j, "old.json").range().known);
}

TEST(OperatingRange, ABadRangeInAModelFileIsOneLineNamingIt) {
  EXPECT_EQ(modelError({{"input", {0, 1}}, {"output", {0, 1}}}), "m.json: range: missing 'input_rate'");
  EXPECT_EQ(modelError({{"input", {2, 1}}, {"output", {0, 1}}, {"input_rate", {0, 1}}}),
            "m.json: range: 'input' must be finite with low <= high");
  EXPECT_EQ(modelError({{"input", {0}}, {"output", {0, 1}}, {"input_rate", {0, 1}}}),
            "m.json: range: 'input' must be [low, high]");
  EXPECT_EQ(modelError({{"input", {0, 1}}, {"output", {0, 1}}, {"input_rate", {0, 1}}, {"speed", {0, 1}}}),
            "m.json: range: unknown key 'speed'");
  EXPECT_EQ(modelError(3), "m.json: range: must be an object with 'input', 'output' and 'input_rate'");
}

TEST(OperatingRange, CompareCountsTheSamplesOutside) {
  const auto d = rampRecord();
  model::OperatingRange r;
  r.known = true;
  r.input = {-1.0, 1.0};   // u > 1 V: samples 201..300 (100 of 302)
  r.output = {-100, 100};  // all inside
  r.rate = {-1.5, 1.5};    // the jump only
  const auto s = diagnose::rangeShare(r, d);
  ASSERT_TRUE(s.known);
  EXPECT_NEAR(s.input, 100.0 / 302, 1e-12);
  EXPECT_EQ(s.output, 0.0);
  EXPECT_NEAR(s.rate, 1.0 / 302, 1e-12);
  EXPECT_NEAR(s.any, 101.0 / 302, 1e-12);
  EXPECT_NE(diagnose::describeRangeShare(s, r).find("33.4 % of the samples (input 33.1 % outside [-1, 1]"),
            std::string::npos)
      << diagnose::describeRangeShare(s, r);
  EXPECT_FALSE(diagnose::rangeShare(model::OperatingRange{}, d).known);
}

TEST(OperatingRange, TheLoopSaysOnceWithTheFirstSampleOutside) {
  model::OperatingRange r;
  r.known = true;
  r.input = {-3.0, 3.0};
  r.output = {4.6, 28.75};
  r.rate = {-50.0, 50.0};
  nodes::RangeWatch w;
  w.configure(r, 1e-3);
  w.step(0.000, 0.0, 10.0);
  w.step(0.001, 0.01, 20.0);
  EXPECT_FALSE(w.outside());
  w.step(0.002, 0.02, 29.5);  // above the output's range
  ASSERT_TRUE(w.outside());
  w.step(0.003, 2.0, 40.0);  // later samples do not replace the first
  const auto line = w.describe();
  EXPECT_NE(line.find("from t = 0.002 s: output 29.5 mm, identified on [4.6, 28.75] mm"), std::string::npos) << line;
  EXPECT_NE(line.find("input rate [-50, 50] V/s"), std::string::npos) << line;
  // A jump of the command faster than any in the record.
  w.configure(r, 1e-3);
  w.step(0.0, 0.0, 10.0);
  w.step(0.001, 0.1, 10.0);
  ASSERT_TRUE(w.outside());
  EXPECT_NE(w.describe().find("input rate 100 V/s"), std::string::npos) << w.describe();
  // No range: nothing is watched.
  w.configure(model::OperatingRange{}, 1e-3);
  w.step(0.0, 99.0, 99.0);
  EXPECT_FALSE(w.outside());
  // The MBC's response monitor: its first verdict against the model is kept, with its ratio, with a range or
  // without.
  w.stepResponse(0.5, false, 1.1);
  EXPECT_FALSE(w.distrusted());
  w.stepResponse(2.0, true, 9.87);
  w.stepResponse(3.0, true, 1.5);
  ASSERT_TRUE(w.distrusted());
  EXPECT_NE(w.describeDistrust().find("from t = 2.000 s: the muscle moved 9.87 times"), std::string::npos)
      << w.describeDistrust();
  w.configure(r, 1e-3);
  EXPECT_FALSE(w.distrusted());
}

namespace {

// The paper's AMC (eq. 17 as printed) held at 15 mm for 2 s, then the position jumps to 1 mm and stays
// there (an empty muscle the model never saw): the UKF's gate gives up and restarts. What the
// controller reports of it over the 600 cycles after the jump.
struct AmcJump {
  explicit AmcJump(const model::OperatingRange& range) {
    control::ControllerConfig c;
    c.model = plant::PlantConfig::modelDefaults().truth;
    c.model.setRange(range);
    auto amc = control::makeController(control::Kind::PiAmc, c);
    amc->activate(0.0, 15.0);
    for (int k = 0; k < 2000; ++k) (void)amc->update(15.0, 15.0, 15.0);
    for (int k = 0; k < 600; ++k) {
      const auto o = amc->update(15.0, 15.0, 1.0);
      resets += o.estimator_reset ? 1 : 0;
      finite = finite && std::isfinite(o.u) && std::isfinite(o.y_hat);
    }
  }
  int resets = 0;
  bool finite = true;
};

}  // namespace

// A model used outside the range it was identified on must not cost the run: the AMC's estimator
// restarting outside the range is no fault (the filter starts over, the loop runs on); with a model
// that records no range, or inside its range, a restart stays a fault as in the paper's form.
TEST(OperatingRange, TheAmcSurvivesItsEstimatorRestartingOutsideTheModelsRange) {
  model::OperatingRange known;
  known.known = true;
  known.input = {-5.0, 5.0};
  known.output = {5.0, 30.0};
  known.rate = {-100.0, 100.0};
  const AmcJump outside(known);
  EXPECT_EQ(outside.resets, 0) << "a restart at 1 mm, outside 5-30 mm, reported as a fault";
  EXPECT_TRUE(outside.finite);
  const AmcJump unknown(model::OperatingRange{});
  EXPECT_EQ(unknown.resets, 1) << "without a range the restart is the fault it always was";
  model::OperatingRange wide = known;
  wide.output = {0.0, 40.0};
  const AmcJump inside(wide);
  EXPECT_EQ(inside.resets, 1) << "inside the range the restart is a fault";
}

// A filter started outside the range carries that start for a while: a restart within a second of
// entering the range is still the range's (no fault); after the filter has run a second inside it, a
// restart is the fault it is in the paper's form.
TEST(OperatingRange, AnAmcRestartCountsAsAFaultOnlyOnceTheFilterHasSettledInsideTheRange) {
  control::ControllerConfig c;
  c.model = plant::PlantConfig::modelDefaults().truth;
  model::OperatingRange r;
  r.known = true;
  r.input = {-5.0, 5.0};
  r.output = {5.0, 30.0};
  r.rate = {-100.0, 100.0};
  c.model.setRange(r);
  auto amc = control::makeController(control::Kind::PiAmc, c);
  amc->activate(0.0, 1.0);
  const auto run = [&](double y, int cycles) {
    int faults = 0;
    const unsigned before = amc->activeModel()->resets();
    for (int k = 0; k < cycles; ++k) faults += amc->update(y, y, y).estimator_reset ? 1 : 0;
    return std::pair<int, int>{faults, static_cast<int>(amc->activeModel()->resets() - before)};
  };
  (void)run(1.0, 500);                   // outside: an empty muscle
  const auto entering = run(25.0, 300);  // into the range, within its first 0.3 s
  EXPECT_GE(entering.second, 1) << "the jump into the range restarts the filter (else this case tests nothing)";
  EXPECT_EQ(entering.first, 0) << "a restart right after entering the range reported as a fault";
  (void)run(25.0, 2000);                // settled inside
  const auto settled = run(12.0, 300);  // a jump inside the range
  EXPECT_GE(settled.second, 1) << "the jump restarts the filter (else this case tests nothing)";
  EXPECT_EQ(settled.first, settled.second) << "a restart of a settled filter inside the range is a fault";
}
