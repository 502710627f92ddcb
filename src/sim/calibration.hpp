// The two-target calibration of the emulator's speed and the reading of the paper's gains: every
// candidate runs the paper's experiments and is judged against Table 1 (open-loop model error) and
// the closed-loop results (Table 2, the square wave, the payload step) at once, with the criteria of
// paper_criteria.hpp. `pamc calibrate` prints the table that docs/CALIBRATION.md shows.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "sim/experiments.hpp"
#include "sim/paper_criteria.hpp"

namespace pamc::sim {

inline ExperimentSettings modelPlantBase() {
  ExperimentSettings e;
  e.plant = plant::PlantConfig::modelDefaults();
  return e;
}

struct CalibrationSettings {
  ExperimentSettings base = modelPlantBase();  // plant (of kind model) and controller defaults the candidates vary
  std::vector<double> lag_tau_s;      // pressure_lag tau of the emulator [s]
  std::vector<double> ki;             // PI integral gain [V/(mm s)]
  std::vector<bool> amc_as_printed;   // eq. (17) as printed / as an increment
  std::vector<double> eso_tau, eso_wo;  // first-order ESO's time constant [s] and bandwidth [rad/s]; empty: base's
  std::string work_dir = "calibration";
  std::function<void(const std::string&)> log;
};

struct CalibrationRow {
  double lag_tau_s = 0, ki = 0;
  bool amc_as_printed = true;
  double eso_tau = 0, eso_wo = 0;
  nlohmann::json summary;               // the experiments' summary.json
  std::vector<Criterion> criteria;
  int met = 0;
  double distance = 0;  // mean |ln(ours / paper)| over Table 1 and Table 2's closed-loop RMSEs
};

std::vector<CalibrationRow> runCalibration(const CalibrationSettings& s);

// Best first: most criteria met, then closest to the paper's numbers.
void rankCalibration(std::vector<CalibrationRow>& rows);

// A Markdown table, the paper's row first; `mark` rows (index into rows) get a bold marker.
std::string formatCalibration(const std::vector<CalibrationRow>& rows, int mark = -1);

}  // namespace pamc::sim
