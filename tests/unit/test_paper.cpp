// The default run shows what the paper shows (docs/CALIBRATION.md): the experiments on the built-in
// emulator with the built-in gains, judged by the same criteria table as `pamc experiments` and
// `pamc calibrate`. Not exact numbers: the claims (ordering, overshoot, settling, ringing, payload).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

#include "sim/calibration.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"
#include "sim/paper_criteria.hpp"

using namespace pamc;

namespace {

const nlohmann::json& defaultRun() {
  static const nlohmann::json j = [] {
    sim::ExperimentSettings s;
    s.plant = plant::PlantConfig::modelDefaults();  // calibrated on the model plant (docs/CALIBRATION.md)
    s.out_dir = (std::filesystem::temp_directory_path() / "pamc_test_paper").string();
    s.figures = false;
    return sim::runExperiments(s).json;
  }();
  return j;
}

}  // namespace

// Every claim the default run is calibrated to (docs/CALIBRATION.md).
TEST(PaperResults, DefaultRunReproducesTheClaims) {
  const auto crit = sim::paperCriteria(defaultRun());
  ASSERT_GE(crit.size(), 11u);
  for (const auto& c : crit) {
    EXPECT_TRUE(c.checked) << c.name;
    EXPECT_TRUE(c.ok) << c.name << ": " << c.claim << " - " << c.detail;
  }
}

// The AMC and PI closed loops: every Table 2 RMSE of PI and AMC within 1.3x of the paper's.
TEST(PaperResults, PiAndAmcWithinTable2) {
  const auto& j = defaultRun();
  for (int r = 0; r < 3; ++r)
    for (int c : {1, 3}) {
      const char* col = c == 1 ? "pi" : "amc";
      const double v = j["table2"][sim::PaperNumbers::table2_rows[r]][col]["rmse"].get<double>();
      const double ratio = v / sim::PaperNumbers::table2[r][c][1];
      EXPECT_LE(ratio, 1.3) << sim::PaperNumbers::table2_rows[r] << " " << col;
      EXPECT_GE(ratio, 1 / 1.3) << sim::PaperNumbers::table2_rows[r] << " " << col;
    }
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

// The calibration varies the first-order ESO like the other readings: one row per (tau, wo), each run
// with its own observer, and the table names them.
TEST(Calibration, VariesTheEsoAndShowsItInTheTable) {
  sim::CalibrationSettings s;
  s.base.only = {"table2"};
  s.lag_tau_s = {0.2};
  s.ki = {1.3};
  s.amc_as_printed = {true};
  s.eso_tau = {0.3};
  s.eso_wo = {0.5, 2.0};
  s.work_dir = (std::filesystem::temp_directory_path() / "pamc_test_calibration").string();
  const auto rows = sim::runCalibration(s);
  ASSERT_EQ(rows.size(), 2u);
  EXPECT_EQ(rows[0].eso_wo, 0.5);
  EXPECT_EQ(rows[1].eso_wo, 2.0);
  const char* tri = sim::PaperNumbers::table2_rows[0];
  const double slow = sim::jsonNumber(rows[0].summary, {"table2", tri, "eso", "rmse"});
  const double fast = sim::jsonNumber(rows[1].summary, {"table2", tri, "eso", "rmse"});
  EXPECT_NE(slow, fast) << "the observer's bandwidth did not reach the runs";
  EXPECT_EQ(sim::jsonNumber(rows[0].summary, {"table2", tri, "pi", "rmse"}),
            sim::jsonNumber(rows[1].summary, {"table2", tri, "pi", "rmse"}));
  const std::string table = sim::formatCalibration(rows);
  EXPECT_NE(table.find("| 0.3 / 0.5 |"), std::string::npos) << table;
  EXPECT_NE(table.find("| 0.3 / 2 |"), std::string::npos) << table;
}
