// The paper's experiments in lockstep simulation on the plant emulator:
//  table1        identification on u0, reference model vs active model on u0, u1, u2 (Table 1)
//  table2        open loop, PI, PID+ESO, PI+AMC on the triangle and descending sines (Table 2)
//  discontinuous square and sawtooth waves: overshoot and settling time (Figure 10)
//  payload       a 40 N payload step while holding: peak deviation and recovery time (Figure 11)
#pragma once

#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "control/controller.hpp"
#include "ident/identify.hpp"
#include "plant/plant.hpp"

namespace pamc::sim {

// Where Table 2's descending sines start. Centre: at their centre, rising, on a muscle parked at the
// trajectory's bottom (0.2 mm, where the triangle starts), scored from the first time the position
// reaches the reference - the paper's sine runs have a start transient (Figs. 8-9; PI's max errors
// 3.77 / 3.27 mm against 1.10 on the triangle), this reproduces it. Trough: at their lowest point,
// where the muscle is parked: no transient.
enum class SineStart { Centre, Trough };

// The plant the paper's experiments run on by default: the physics plant with the free parameters that
// `pamc calibrate` fitted to Table 1 and Table 2's triangle row (calibration.cpp, docs/CALIBRATION.md),
// and the words the summary records for that.
plant::PlantConfig paperPlant();
// The controller defaults with the reading of ki that calibration chose (the paper's ESO is the
// default of every controller).
control::ControllerConfig paperController();
extern const char* const kCalibratedOn;

struct ExperimentSettings {
  std::string out_dir = "results";
  plant::PlantConfig plant = paperPlant();
  std::string calibrated_on = kCalibratedOn;  // the readings' record of what the plant was fitted to
  control::ControllerConfig ctrl = paperController();  // gains and UKF settings; the model comes from table1's fit
  ident::FitSettings fit{};
  std::string model_file;            // use this model instead of identifying one
  SineStart sine_start = SineStart::Centre;
  bool figures = true;
  // Empty: all. Else any of table1 (always runs), table2, triangle (Table 2's triangle row alone),
  // discontinuous, payload.
  std::vector<std::string> only;
  bool table1 = true;  // false (with model_file): skip Table 1's records (a calibration's second gain)
  std::function<void(const std::string&)> log;
};

struct ExperimentReport {
  nlohmann::json json;
  std::string text;  // the tables, beside the paper's figures
};

ExperimentReport runExperiments(const ExperimentSettings& s);

// Table 1's analysis of one record: reference-model RMSE, UKF posterior and one-step-ahead
// RMSE, and the persistence predictor y_{k-1} for scale.
struct ModelAccuracy {
  double reference_rmse = 0, posterior_rmse = 0, one_step_rmse = 0, persistence_rmse = 0;
};
ModelAccuracy modelAccuracy(const model::Model& m, const estimation::ActiveModelSettings& ukf,
                            const std::vector<double>& u, const std::vector<double>& y, double Ts,
                            std::vector<double>* y_ref = nullptr, std::vector<double>* y_post = nullptr);

}  // namespace pamc::sim
