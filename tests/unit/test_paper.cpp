// The paper as a held-out test: the claims table (src/sim/paper_claims.cpp) computes its verdicts from
// a run, the calibration reads only the calibrated claims, and the run's metrics measure what they say.
// No test here checks that a claim holds: that is what `pamc experiments` reports (docs/EXPERIMENTS.md).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <set>
#include <stdexcept>

#include "sim/calibration.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"
#include "sim/paper_claims.hpp"

using namespace pamc;

namespace {

// A summary with every figure the claims read, each the paper's own value times `scale`.
nlohmann::json paperLikeSummary(double scale) {
  nlohmann::json s;
  for (const auto& c : sim::paperClaims())
    for (const auto* paths : {&c.test.a, &c.test.b})
      for (const auto& p : *paths) {
        nlohmann::json::json_pointer ptr("/" + p);
        const double v = c.test.kind == sim::ClaimTest::Kind::Near ? c.test.paper * scale : 1.0;
        if (!s.contains(ptr)) s[ptr] = v;
      }
  return s;
}

const sim::ClaimResult& resultOf(const std::vector<sim::ClaimResult>& r, const std::string& id) {
  for (const auto& x : r)
    if (x.claim->id == id) return x;
  throw std::runtime_error("no claim " + id);
}

}  // namespace

// The table: enough rows, unique ids, calibrated rows only where the paper tuned (Table 1 and the
// triangle), every row with a claim in words, a paper figure and a path the summary has.
TEST(PaperClaims, TableIsCompleteAndCalibratesOnlyTheTuningTargets) {
  const auto& t = sim::paperClaims();
  EXPECT_GE(t.size(), 20u);
  std::set<std::string> ids;
  int calibrated = 0;
  for (const auto& c : t) {
    EXPECT_TRUE(ids.insert(c.id).second) << c.id;
    EXPECT_FALSE(c.claim.empty() || c.paper.empty() || c.where.empty()) << c.id;
    ASSERT_FALSE(c.test.a.empty()) << c.id;
    if (c.role != sim::ClaimRole::Calibrated) continue;
    ++calibrated;
    for (const auto& p : c.test.a)
      EXPECT_TRUE(p.rfind("table1/", 0) == 0 || p.rfind("table2/triangle_0.05Hz/", 0) == 0) << c.id << ": " << p;
  }
  EXPECT_EQ(calibrated, 3 + 8);  // Table 1's three RMSEs; the triangle row's max and RMSE of four controllers
}

// Verdicts come from the run: a summary at the paper's values reproduces the Near claims; moving one
// figure out of its threshold turns that verdict, and only that one.
TEST(PaperClaims, VerdictsFollowTheRun) {
  auto s = paperLikeSummary(1.0);
  const auto base = sim::judgeClaims(s);
  EXPECT_EQ(resultOf(base, "t2_sine05_amc_rmse").verdict, sim::Verdict::Reproduced);
  EXPECT_EQ(resultOf(base, "t1_u0").verdict, sim::Verdict::Calibrated);
  s["table2"]["sine_0.05Hz"]["amc"]["rmse"] = 0.1934 * 1.5;
  const auto moved = sim::judgeClaims(s);
  EXPECT_EQ(resultOf(moved, "t2_sine05_amc_rmse").verdict, sim::Verdict::NotReproduced);
  EXPECT_EQ(resultOf(moved, "t2_sine05_pi_rmse").verdict, sim::Verdict::Reproduced);
  // A missing section is not run, not failed.
  s.erase("payload");
  EXPECT_EQ(resultOf(sim::judgeClaims(s), "payload_amc_faster_pi").verdict, sim::Verdict::NotRun);
  const auto n = sim::countClaims(sim::judgeClaims(s));
  EXPECT_GT(n.not_run, 0);
  const auto j = sim::claimsJson(moved);
  ASSERT_EQ(j.size(), sim::paperClaims().size());
  for (const char* k : {"claim", "paper", "value", "threshold", "verdict"}) EXPECT_TRUE(j[0].contains(k)) << k;
}

// The words' thresholds as the table applies them: below, at most, spread.
TEST(PaperClaims, ThresholdKinds) {
  nlohmann::json s = paperLikeSummary(1.0);
  s["discontinuous"]["square"]["forward"]["amc"]["overshoot_pct"] = 1.9;
  EXPECT_TRUE(resultOf(sim::judgeClaims(s), "square_fwd_amc_negligible").holds);
  s["discontinuous"]["square"]["forward"]["amc"]["overshoot_pct"] = 2.1;
  EXPECT_FALSE(resultOf(sim::judgeClaims(s), "square_fwd_amc_negligible").holds);
  s["discontinuous"]["square"]["backward"]["pi"]["settling_s"] = 0.4;
  s["discontinuous"]["square"]["backward"]["eso"]["settling_s"] = 0.5;
  s["discontinuous"]["square"]["backward"]["amc"]["settling_s"] = 0.59;
  EXPECT_TRUE(resultOf(sim::judgeClaims(s), "square_bwd_comparable").holds);
  s["discontinuous"]["square"]["backward"]["amc"]["settling_s"] = 0.61;
  EXPECT_FALSE(resultOf(sim::judgeClaims(s), "square_bwd_comparable").holds);
  s["payload"]["amc"]["recovery_s"] = 1.0;
  s["payload"]["pi"]["recovery_s"] = 1.0;
  EXPECT_FALSE(resultOf(sim::judgeClaims(s), "payload_amc_faster_pi").holds);  // strictly faster
}

// The calibration sees only its targets: changing every predicted claim's paper figure and threshold
// leaves its choice where it was; changing a calibrated target moves it.
TEST(Calibration, ChoiceIgnoresEveryPredictedTarget) {
  std::vector<sim::CalibrationPoint> pts;
  for (double scale : {0.6, 0.9, 1.25, 2.0}) {
    sim::CalibrationPoint p;
    p.summary = paperLikeSummary(scale);
    // Predicted figures that favour another point than the calibrated ones do.
    p.summary["table2"]["sine_0.05Hz"]["amc"]["rmse"] = 0.1934 / scale;
    pts.push_back(p);
  }
  const size_t chosen = sim::chooseCalibration(pts, sim::paperClaims());
  EXPECT_EQ(chosen, 1u);  // 0.9 is the closest to the paper on the calibrated rows
  auto changed = sim::paperClaims();
  for (auto& c : changed) {
    if (c.role == sim::ClaimRole::Calibrated) continue;
    c.test.paper *= 3.0;
    c.test.factor *= 2.0;
    c.test.hi *= 5.0;
    EXPECT_EQ(sim::chooseCalibration(pts, changed), chosen) << "after changing " << c.id;
  }
  auto target = sim::paperClaims();
  for (auto& c : target)
    if (c.role == sim::ClaimRole::Calibrated) c.test.paper *= 2.0;
  EXPECT_EQ(sim::chooseCalibration(pts, target), 3u);  // now the 2.0x point matches
}

// The free parameters of the plant: at most four, each changing the field it names.
TEST(Calibration, AxesSetTheirParameters) {
  const auto& axes = sim::calibrationAxes();
  ASSERT_LE(axes.size(), 4u);
  std::vector<double> nominal;
  for (const auto& a : axes) nominal.push_back(a.nominal);
  const auto base = sim::plantWith(nominal).toJson();
  EXPECT_EQ(base, plant::PlantConfig::defaults().toJson()) << "the nominal values are the plant's defaults";
  for (size_t i = 0; i < axes.size(); ++i) {
    auto v = nominal;
    v[i] = axes[i].values.back() == axes[i].nominal ? axes[i].values.front() : axes[i].values.back();
    EXPECT_NE(sim::plantWith(v).toJson(), base) << axes[i].name;
  }
}

// Turning points: the error after each corner of a triangle, nothing for a constant.
TEST(Metrics, TurningPointErrorAndWindowRmse) {
  sim::Record r;
  for (int k = 0; k < 20000; ++k) {
    const double t = k * 1e-3;
    const double yd = t < 10 ? t : 20 - t;  // one corner at t = 10
    r.t.push_back(t);
    r.yd.push_back(yd);
    r.y.push_back(yd + (t > 10.2 && t < 10.3 ? 0.5 : 0.0) + (t > 15 && t < 15.1 ? 2.0 : 0.0));
  }
  EXPECT_NEAR(sim::turningPointError(r, 1.0), 0.5, 1e-12);  // the late bump is not after a corner
  EXPECT_NEAR(sim::windowRmse(r, 15.01, 15.09), 2.0, 1e-9);
  EXPECT_NEAR(sim::windowRmse(r, 0.0, 5.0), 0.0, 1e-12);
  for (auto& y : r.yd) y = 3.0;
  EXPECT_EQ(sim::turningPointError(r, 1.0), 0.0);
}

// The sines of Table 2 start at their centre, rising; the dictionary cannot hold that start, so a node
// given such a trajectory keeps it as an override; the spec form takes the phase in degrees.
TEST(SineStart, CentreStartRisesFromTheCentre) {
  const auto trough = control::Trajectory::sineDescending(0.1, 15.1, 14.9, 3.0, 30.0);
  const auto centre = control::Trajectory::sineDescending(0.1, 15.1, 14.9, 3.0, 30.0, M_PI / 2);
  EXPECT_NEAR(trough.at(0.0), 0.2, 1e-12);
  EXPECT_NEAR(centre.at(0.0), 15.1, 1e-12);
  EXPECT_GT(centre.at(0.5), 15.1 + 4.0);  // rising at 2 pi f A = 9.4 mm/s
  const auto parsed = control::Trajectory::parse("sinedesc:0.1:15.1:14.9:3:30:90");
  EXPECT_NEAR(parsed.at(1.234), centre.at(1.234), 1e-9);
  EXPECT_THROW(control::Trajectory::parse("sinedesc:0.1:15.1:14.9:3:30:90:1"), std::invalid_argument);
}

// Scoring from the first reach: the rise from home is left out, the overshoot after it is kept.
TEST(SineStart, FirstReachLeavesOutTheRiseOnly) {
  sim::Record r;
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.01 * i;
    r.t.push_back(t);
    r.yd.push_back(10.0);
    r.y.push_back(t < 0.5 ? 20.0 * t : 10.0 + 2.0 * std::sin(6.0 * (t - 0.5)));  // rise, then overshoot
  }
  EXPECT_NEAR(sim::firstReach(r), 0.5, 1e-12);
  const auto st = sim::tracking(r, sim::firstReach(r));
  EXPECT_NEAR(st.max_abs, 2.0, 0.01);
  EXPECT_GT(sim::tracking(r).max_abs, 9.0);
  sim::Record never = r;
  for (auto& y : never.y) y = 0.0;
  EXPECT_NEAR(sim::firstReach(never), 1.0, 1e-12);
}

// The ringing measure itself: a clean first-order step has no crossings and one command move; a
// step that rings at 3 Hz is caught.
TEST(StepResponse, RingingMeasure) {
  auto make = [](bool ring) {
    sim::Record r;
    for (int k = 0; k < 4000; ++k) {
      const double t = k * 1e-3;
      const bool after = t >= 1.0;
      const double ts = t - 1.0;
      double y = 10.0;
      if (after) {
        y = 10.0 + 15.0 * (1.0 - std::exp(-ts / 0.1));
        if (ring) y += 3.0 * std::exp(-ts / 1.0) * std::sin(2 * M_PI * 3.0 * ts);
      }
      r.t.push_back(t);
      r.yd.push_back(after ? 25.0 : 10.0);
      r.y.push_back(y);
      r.u.push_back(0.1 * (r.yd.back() - y) + (after ? 1.0 : 0.0));
    }
    return r;
  };
  const auto clean = sim::stepResponse(make(false), +1, 1.0, 0.02);
  EXPECT_EQ(clean.steps, 1);
  EXPECT_EQ(clean.max_error_crossings, 0);
  EXPECT_LE(clean.max_u_reversals, 1);
  const auto ringing = sim::stepResponse(make(true), +1, 1.0, 0.02);
  EXPECT_GT(ringing.max_error_crossings, 2);
  EXPECT_GT(ringing.max_u_reversals, 3);
}

// A run computes its verdicts: the payload claims on the calibrated plant and on one with a valve four
// times narrower (the same controller) come out with other values, each judged.
TEST(PaperClaims, AChangedPlantChangesTheJudgedValues) {
  auto runOn = [](const plant::PlantConfig& p, const std::string& dir) {
    sim::ExperimentSettings s;
    s.plant = p;
    s.only = {"payload"};
    s.figures = false;
    s.out_dir = (std::filesystem::temp_directory_path() / dir).string();
    return sim::judgeClaims(sim::runExperiments(s).json);
  };
  plant::PlantConfig slow = sim::paperPlant();
  slow.physics.regulator.conductance_dm3_per_s_bar /= 4.0;
  const auto a = runOn(sim::paperPlant(), "pamc_test_claims_a");
  const auto b = runOn(slow, "pamc_test_claims_b");
  for (const char* id : {"payload_amc_faster_pi", "payload_amc_faster_eso", "steady_noise_amc"}) {
    const auto& ra = resultOf(a, id);
    const auto& rb = resultOf(b, id);
    EXPECT_NE(ra.verdict, sim::Verdict::NotRun) << id;
    EXPECT_NE(rb.verdict, sim::Verdict::NotRun) << id;
    EXPECT_NE(ra.value, rb.value) << id;
  }
  EXPECT_EQ(resultOf(a, "t2_sine05_amc_rmse").verdict, sim::Verdict::NotRun);
}
