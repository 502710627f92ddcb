// The protocol of docs/CALIBRATION.md: the paper tuned its controllers on the triangle and then fixed
// every parameter. So the physics plant's free parameters (the table of calibrationAxes(), at most four)
// and the reading of ki are fitted to the calibrated claims of paper_claims.cpp only - Table 1 and
// Table 2's triangle row - by a coordinate search; every other claim is a prediction of the fitted plant.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/experiments.hpp"
#include "sim/paper_claims.hpp"

namespace pamc::sim {

// One free parameter of the plant: its name, unit, the values the search tries and what it sets.
struct CalibrationAxis {
  std::string name, unit, physics;
  std::vector<double> values;
  double nominal = 0;  // the datasheet/assumption value of docs/PHYSICS.md
  void (*apply)(plant::PlantConfig&, double) = nullptr;
};
const std::vector<CalibrationAxis>& calibrationAxes();

// A point of the search: the plant's free parameters (per calibrationAxes()) and the reading of ki.
struct CalibratedReading {
  std::vector<double> plant_values;
  double ki = 0;
};
// The physics plant's defaults with the axes set to `values`.
plant::PlantConfig plantWith(const std::vector<double>& values);

struct CalibrationPoint;
// Evaluates a step's candidate plants (each a vector of the axes' values), in the batch's order: the
// points of each (evaluateCalibrationPlant). A cluster's workers can stand in for the threads.
using CalibrationEvaluator =
    std::function<std::vector<std::vector<CalibrationPoint>>(const std::vector<std::vector<double>>& batch)>;

struct CalibrationSettings {
  ExperimentSettings base{};  // its plant's free parameters are overwritten per point
  std::vector<double> ki_grid = {0.15, 0.5, 1.0, 1.3, 1.5, 1.7, 2.0, 2.5, 3.0, 4.0};
  int passes = 2;
  int threads = 2;
  CalibrationEvaluator evaluate;  // empty: the batch on `threads` threads here
  std::vector<std::string> axes;  // the free parameters searched (names; empty: all); the others stay nominal
  std::string work_dir = "calibration";
  std::vector<Claim> claims = paperClaims();  // only the calibrated rows are read
  std::function<void(const std::string&)> log;
};

struct CalibrationPoint {
  CalibratedReading reading;
  nlohmann::json summary;  // Table 1 and the triangle row
  double distance = 0;     // calibrationDistance
};

struct CalibrationResult {
  std::vector<CalibrationPoint> tried;
  size_t best = 0;
};

CalibrationResult runCalibration(const CalibrationSettings& s);

// Every reading of ki on one plant: Table 1 and the identification once, then the triangle per ki (the
// runs in s.work_dir/<values>/).
std::vector<CalibrationPoint> evaluateCalibrationPlant(const CalibrationSettings& s, const std::vector<double>& values);

nlohmann::json calibrationPointToJson(const CalibrationPoint& p);
CalibrationPoint calibrationPointFromJson(const nlohmann::json& j);

// The index of the point with the smallest calibration distance under `claims`.
size_t chooseCalibration(const std::vector<CalibrationPoint>& points, const std::vector<Claim>& claims);

// A Markdown table of the points tried, the paper's row first, the chosen one in bold.
std::string formatCalibration(const CalibrationResult& r);

}  // namespace pamc::sim
