// pamc robustness (src/sim/robustness.hpp): the axis table, the selection of axes, a short run.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "sim/robustness.hpp"

using namespace pamc;

namespace {

// The plant file's value at a dotted key ("regulator.supply_bar").
double fieldOf(const plant::PlantConfig& p, const std::string& field) {
  nlohmann::json j = p.toJson();
  std::stringstream ss(field);
  std::string part;
  while (std::getline(ss, part, '.')) j = j.at(part);
  return j.get<double>();
}

std::vector<std::vector<std::string>> readCsv(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(f, line)) {
    rows.emplace_back();
    std::stringstream ss(line);
    std::string cell;
    while (std::getline(ss, cell, ',')) rows.back().push_back(cell);
  }
  return rows;
}

const sim::RobustnessAxis& axisNamed(const std::vector<sim::RobustnessAxis>& axes, const std::string& name) {
  for (const auto& a : axes)
    if (a.name == name) return a;
  throw std::runtime_error("no axis " + name);
}

}  // namespace

// Every plant axis sets the field it names (and nothing reads the nominal back); every axis has at least
// five ascending values with its nominal among them.
TEST(Robustness, AxisTableAppliesEachAxisToItsField) {
  const auto nominal = plant::PlantConfig::defaults();
  const auto axes = sim::robustnessAxes(nominal);
  ASSERT_EQ(axes.size(), 5u);
  for (const auto& a : axes) {
    SCOPED_TRACE(a.name);
    EXPECT_GE(a.values.size(), 5u);
    EXPECT_TRUE(std::is_sorted(a.values.begin(), a.values.end()));
    EXPECT_NE(std::find(a.values.begin(), a.values.end(), a.nominal), a.values.end());
    if (a.changesModel()) {
      EXPECT_TRUE(a.field.empty());
      EXPECT_EQ(a.nominal, sim::kIdentAmplitude);
      continue;
    }
    EXPECT_DOUBLE_EQ(fieldOf(nominal, a.field), a.nominal);
    for (double v : a.values) {
      plant::PlantConfig p = nominal;
      a.apply(p, v);
      EXPECT_DOUBLE_EQ(fieldOf(p, a.field), v);
      if (v != a.nominal) {
        EXPECT_TRUE(p.toJson() != nominal.toJson()) << "the plant file did not change";
      }
    }
  }
  // The supply axis reaches below the 8 bar the top of the command asks for, and above it.
  const auto& supply = axisNamed(axes, "supply");
  EXPECT_LT(supply.values.front(), 8.0);
  EXPECT_GE(supply.values.back(), 8.0);
  // The noise axis reaches the plant the Plant builds (its sensor), not only the file.
  plant::PlantConfig quiet = nominal;
  axisNamed(axes, "noise").apply(quiet, 0.0);
  EXPECT_FALSE(quiet.sensor_noise);
}

TEST(Robustness, UnknownAxisThrowsNamingIt) {
  const auto axes = sim::robustnessAxes(plant::PlantConfig::defaults());
  try {
    sim::selectAxes(axes, {"flow", "valve_speed"});
    FAIL() << "no throw";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'valve_speed'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("flow, mass, supply, noise, model"), std::string::npos) << e.what();
  }
  const auto two = sim::selectAxes(axes, {"model", "flow"});
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].name, "flow");  // the table's order
  EXPECT_EQ(sim::selectAxes(axes, {}).size(), axes.size());
}

// A short run: two axes of two values each (shortened trajectories, the fast fit), the CSVs with finite
// ratios, a changed plant changing them, and the 2x2 grid.
TEST(Robustness, ShortRunWritesFiniteRatiosThatMoveWithThePlant) {
  sim::RobustnessSettings s;
  s.out_dir = (std::filesystem::temp_directory_path() / "pamc_test_robustness").string();
  std::filesystem::remove_all(s.out_dir);
  s.figures = false;
  s.duration_scale = 0.15;
  s.fit = ident::FitSettings::forMethod(ident::FitMethod::MultiStart);
  auto all = sim::robustnessAxes(s.plant);
  auto flow = axisNamed(all, "flow"), mass = axisNamed(all, "mass");
  flow.values = {0.4 * flow.nominal, flow.nominal};
  mass.values = {mass.nominal, 2.0 * mass.nominal};
  s.axes = {flow, mass};
  const auto rep = sim::runRobustness(s);

  const auto rows = readCsv(s.out_dir + "/axis_flow.csv");
  ASSERT_EQ(rows.size(), 1u + 2u * 4u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"value", "trajectory", "pi_rmse", "eso_rmse", "amc_rmse", "amc_over_pi",
                                               "eso_over_pi", "mbc_rmse", "mbc_over_pi"}));
  bool moved = false;
  for (size_t i = 1; i < rows.size(); ++i) {
    ASSERT_EQ(rows[i].size(), 9u);
    for (size_t c : {2u, 3u, 4u, 5u, 6u, 7u, 8u}) {
      const double v = std::stod(rows[i][c]);
      EXPECT_TRUE(std::isfinite(v) && v > 0.0) << rows[i][c];
    }
    if (i <= 4) {  // the same trajectory at the nominal flow, four rows later
      EXPECT_EQ(rows[i][1], rows[i + 4][1]);
      moved = moved || std::fabs(std::stod(rows[i][5]) - std::stod(rows[i + 4][5])) > 1e-4;
    }
  }
  EXPECT_TRUE(moved) << "0.4x the valve flow left every AMC/PI ratio as it was";

  // One window for the three runs of a trajectory: from the start where it starts at home (the triangle),
  // from a first reach after the start where it does not (the sines).
  for (const auto& sc : rep.axes[0].scores[0]) {
    ASSERT_TRUE(std::isfinite(sc.scored_from_s)) << sc.trajectory;
    if (sc.trajectory.rfind("sine", 0) == 0) {
      EXPECT_GT(sc.scored_from_s, 0.0) << sc.trajectory;
    } else {
      EXPECT_EQ(sc.scored_from_s, 0.0) << sc.trajectory;
    }
  }

  ASSERT_EQ(rep.strongest.size(), 2u);
  EXPECT_EQ(rep.variants, 4);  // nominal, flow, mass and the grid's corner: each run once
  EXPECT_EQ(readCsv(s.out_dir + "/grid.csv").size(), 1u + 2u * 2u * 4u);
  EXPECT_TRUE(std::filesystem::exists(s.out_dir + "/summary.json"));
  EXPECT_TRUE(std::filesystem::exists(s.out_dir + "/summary.txt"));
}
