// Where the active model control helps beyond the paper (`pamc robustness`, docs/EXPERIMENTS.md): PI,
// PID+ESO and PI+AMC with the experiments' gains on Table 2's three trajectories and the square wave, over
// plant changes the controllers were not tuned for - one axis at a time around the nominal plant, then
// the full grid of the two axes along which the AMC/PI RMSE ratio spreads most. Plant axes keep the
// nominal model; the model axis changes only the model (identified on another amplitude of u0).
//
// A run is made of cells (one plant/model variant: 4 trajectories x 4 controllers) in two phases - the
// axes, then the pairs grid chosen from the axes' result - and each phase can be split into parts run
// anywhere (--shard I/N) whose cells documents are merged into the files one run writes (--merge).
#pragma once

#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "control/controller.hpp"
#include "ident/identify.hpp"
#include "plant/plant.hpp"
#include "sim/experiments.hpp"

namespace pamc::sim {

// One axis of change: its values (the nominal among them) and what a value changes.
struct RobustnessAxis {
  std::string name;   // as --only-axes names it
  std::string label;  // for people: "valve flow (sonic conductance C)"
  std::string unit;
  std::string field;  // the plant file's key it sets ("regulator.supply_bar"); empty for the model axis
  double nominal = 0.0;
  std::vector<double> values;  // ascending, the nominal included
  bool physics_only = false;   // the field exists in the physics plant only
  // Sets the value in the plant's configuration; empty for the model axis, whose value is the amplitude
  // [V] of the identification input the controller's model is fitted on.
  std::function<void(plant::PlantConfig&, double)> apply;
  bool changesModel() const { return field.empty(); }
};

// The table of axes around a nominal plant - the one place where the list of axes lives.
std::vector<RobustnessAxis> robustnessAxes(const plant::PlantConfig& nominal);
// The axes named (empty: all), in the table's order; throws std::invalid_argument naming an unknown one.
std::vector<RobustnessAxis> selectAxes(const std::vector<RobustnessAxis>& all, const std::vector<std::string>& names);

// The trajectories: Table 2's three (sines from their centre, as in the experiments) and the square wave,
// their durations times `duration_scale` (< 1: shortened, for tests).
std::vector<TrackingCase> robustnessCases(double duration_scale = 1.0);

// The I-th of N parts of a phase's cells (1 <= I <= N): every N-th cell from the I-th.
struct Shard {
  int index = 1, count = 1;
};
// "I/N"; throws std::invalid_argument saying what is wrong.
Shard parseShard(const std::string& text);

struct RobustnessSettings {
  std::string out_dir = "robustness";
  plant::PlantConfig plant = ExperimentSettings{}.plant;       // the nominal plant
  control::ControllerConfig ctrl = ExperimentSettings{}.ctrl;  // gains; the model is identified or read
  ident::FitSettings fit = ExperimentSettings{}.fit;
  std::string model_file;              // the nominal model from this file instead of identifying one
  std::vector<std::string> only_axes;  // empty: every axis of the table
  std::vector<RobustnessAxis> axes;    // empty: robustnessAxes(plant) (tests pass reduced ones)
  double duration_scale = 1.0;         // trajectories shortened for tests
  // The three runs of a trajectory scored over the same window: from the latest of their first reaches
  // (false: each from its own, Table 2's rule; see scoreCase in robustness.cpp).
  bool common_window = true;
  bool grid = true;  // the 5x5 grid of the two strongest axes
  bool figures = true;
  int threads = 2;  // worker threads over the independent runs
  Shard shard;      // the part of the phase's cells to run (runRobustnessCells)
  std::function<void(const std::string&)> log;
};

// RMSE of the four controllers on one trajectory for one variant.
struct RobustnessScore {
  std::string trajectory;
  double pi = 0.0, eso = 0.0, amc = 0.0, mbc = 0.0;
  double scored_from_s = NAN;  // the common window's start (NaN: each run from its own first reach)
  double amcOverPi() const { return amc / pi; }
  double esoOverPi() const { return eso / pi; }
  double mbcOverPi() const { return mbc / pi; }
};

struct AxisResult {
  RobustnessAxis axis;
  std::vector<std::vector<RobustnessScore>> scores;  // [value][trajectory]
  std::vector<double> mean_amc_over_pi;              // per value, over the trajectories
  double spread = 0.0;                               // max - min of mean_amc_over_pi
};

struct GridResult {
  std::string row_axis, col_axis;
  std::vector<double> row_values, col_values;
  std::vector<std::vector<std::vector<RobustnessScore>>> scores;  // [row][col][trajectory]
};

struct RobustnessReport {
  std::vector<AxisResult> axes;
  std::vector<std::string> strongest;  // the two axes of the grid (fewer when fewer axes ran)
  GridResult grid;                     // empty when no grid ran
  int variants = 0;                    // plant/model variants run (each 4 trajectories x 4 controllers)
  double seconds = 0.0;                // the runs' time, the parts' times added
  int shards = 1;                      // parts the cells were run in (the larger of the two phases)
  bool pairs_pending = false;          // the grid is due and its cells are not run yet (--pairs-of)
  nlohmann::json json;
  std::string text;
};

// The whole run: the axes' cells, the pairs' cells, the files (runRobustnessCells twice, then
// mergeRobustness).
RobustnessReport runRobustness(const RobustnessSettings& s);

// One part of a phase: without `axes_cells` the axes, with it (a document holding every axis cell) the
// pairs grid chosen from them. Runs the part `s.shard` of the phase's cells not yet in `axes_cells`,
// identifies the models they need (ident_A*.csv in s.out_dir), and returns - and writes to
// s.out_dir/cells.json - the cells document: the settings (robustnessSettingsJson), the models, the cells
// inherited and run. With `axes_cells` the settings are its own (s gives only out_dir, shard, threads, log).
nlohmann::json runRobustnessCells(const RobustnessSettings& s, const nlohmann::json* axes_cells = nullptr);

// Combines cells documents (every part of one phase, or one complete document) into the files a single
// run writes in out.out_dir (out also gives figures and log), and cells.json with all cells; the pairs
// grid is left pending when its cells are not among them. Throws std::invalid_argument naming a part
// that is missing, given twice or run with other settings.
RobustnessReport mergeRobustness(const std::vector<nlohmann::json>& docs, const RobustnessSettings& out);

// DIR/cells.json, with DIR recorded in it for the merge's messages; throws io::InputError naming it.
nlohmann::json readRobustnessCells(const std::string& dir);

// What makes cells comparable: the plant, the controller settings, the fit, the axes with their values,
// the trajectories' scale, the scoring window and whether the grid runs. The settings it describes
// (robustnessSettingsFromJson) run the same cells.
nlohmann::json robustnessSettingsJson(const RobustnessSettings& s);
RobustnessSettings robustnessSettingsFromJson(const nlohmann::json& j);

}  // namespace pamc::sim
