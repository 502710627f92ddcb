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
#include "sim/lockstep.hpp"

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
extern const char* const kCalibratedOn;

struct ExperimentSettings {
  std::string out_dir = "results";
  plant::PlantConfig plant = paperPlant();
  std::string calibrated_on = kCalibratedOn;  // the readings' record of what the plant was fitted to
  // Gains (control::kDefaultGains: ki the reading calibration chose), the paper's ESO and the UKF
  // settings, all ControllerConfig's defaults; the model comes from table1's fit.
  control::ControllerConfig ctrl;
  ident::FitSettings fit{};
  std::string model_file;  // use this model instead of identifying one
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

// Throws std::invalid_argument on an unknown name in `only`, before anything is written.
ExperimentReport runExperiments(const ExperimentSettings& s);

// A closed-loop run of the experiments under its name (the tag of its files and rows).
struct TrackingCase {
  std::string tag;
  ClosedLoopRun run;
};
// Table 2's trajectories: the 0.05 Hz triangle 0.2..30 mm (40 s), the descending sines 0.05 Hz (60 s)
// and 0.1 Hz (30 s) started as `start` says.
std::vector<TrackingCase> table2Cases(SineStart start);
// The discontinuous trajectories: the 0.1 Hz square and sawtooth waves 10..25 mm, 30 s each.
std::vector<TrackingCase> discontinuousCases();

// The controller of the experiments: the gains and estimator settings of `gains` with the model `m`, the
// plant's sample time and command range.
control::ControllerConfig controllerFor(const control::ControllerConfig& gains, const model::Model& m,
                                        const plant::PlantConfig& plant);
// One closed-loop run of a fresh controller of `kind` on a fresh plant, started at the inverse of the
// run's home position, with the controller's bus delay. Shares nothing mutable between calls.
Record runController(control::Kind kind, const control::ControllerConfig& cc, const control::InverseStatic& inv,
                     const plant::PlantConfig& plant, const ClosedLoopRun& run);

// Table 1's identification input: u = amplitude sin(0.2 pi t) + 0.2 V (u0: amplitude 2.9 V), recorded
// for kIdentDuration seconds in open loop.
constexpr double kIdentDuration = 40.0;
constexpr double kIdentAmplitude = 2.9;
Trajectory identInput(double amplitude = kIdentAmplitude);
// The plant excited by u in open loop for duration_s from rest; the record written to csv (t,u,y,p).
Record recordOpenLoop(const plant::PlantConfig& plant, const Trajectory& u, double duration_s, const std::string& csv);
// Table 1's fit: the Bouc-Wen model (ident::fit from model::Model{}) on the record in `csv` (t,u,y),
// the GA's progress every 25 generations to `log` (may be empty).
ident::FitResult identifyOnRecord(const std::string& csv, const ident::FitSettings& fit,
                                  const std::function<void(const std::string&)>& log);

// Table 1's analysis of one record: reference-model RMSE, UKF posterior and one-step-ahead
// RMSE, and the persistence predictor y_{k-1} for scale.
struct ModelAccuracy {
  double reference_rmse = 0, posterior_rmse = 0, one_step_rmse = 0, persistence_rmse = 0;
};
ModelAccuracy modelAccuracy(const model::Model& m, const estimation::ActiveModelSettings& ukf,
                            const std::vector<double>& u, const std::vector<double>& y, double Ts,
                            std::vector<double>* y_ref = nullptr, std::vector<double>* y_post = nullptr);

}  // namespace pamc::sim
