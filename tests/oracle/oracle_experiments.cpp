// pamc_oracle_experiments: the paper's experiments (`pamc experiments`) with the oracle's simulator as the
// plant - a second plant that shares no code with the physics plant or src/model, for judging controllers
// on physics they were not tuned on (tools/mbc_table.py --oracle-plant, docs/CONTROL.md).
//
// The oracle library itself stays free of pamc; this harness hands its chain, as a plant of kind external
// (oracle_plant.hpp), to sim::runExperiments.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <string>
#include <vector>

#include "oracle_plant.hpp"
#include "sim/experiments.hpp"

namespace {

using namespace pamc;

oracle::Case findCase(const std::string& path, const std::string& name) {
  const auto cases = oracle::loadCases(path);
  if (name.empty() && cases.size() == 1) return cases.front();
  for (const auto& c : cases)
    if (c.name == name) return c;
  throw std::invalid_argument(path + ": no case '" + name + "' (give --case when the file holds several)");
}

struct Options {
  std::string cases, case_name, model, out_dir = "results-oracle";
  std::vector<std::string> only;
  bool no_figures = false;
  int mbc_horizon = 0;
  double mbc_rate = control::ControllerConfig{}.mbc.rate_mm_s;
  double mbc_accel = control::ControllerConfig{}.mbc.accel_mm_s2;
  double mbc_accel_carried = control::ControllerConfig{}.mbc.accel_carried_mm_s2;
  double mbc_pace_share = control::ControllerConfig{}.mbc.pace_share;
};

int run(const Options& o) {
  const oracle::Case c = findCase(o.cases, o.case_name);
  sim::ExperimentSettings s;
  s.plant = oracle::oraclePlant(c);
  s.calibrated_on = "not calibrated: the oracle's case " + c.name + " of " + o.cases;
  s.out_dir = o.out_dir;
  s.model_file = o.model;
  s.figures = !o.no_figures;
  s.ctrl.mbc.horizon = o.mbc_horizon;
  s.ctrl.mbc.rate_mm_s = o.mbc_rate;
  s.ctrl.mbc.accel_mm_s2 = o.mbc_accel;
  s.ctrl.mbc.accel_carried_mm_s2 = o.mbc_accel_carried;
  s.ctrl.mbc.pace_share = o.mbc_pace_share;
  s.only = o.only;
  s.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  const auto rep = sim::runExperiments(s);
  std::printf("%s", rep.text.c_str());
  std::printf("results in %s/ (summary.json)\n", o.out_dir.c_str());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{
      "pamc_oracle_experiments: the paper's experiments (pamc experiments) on the test oracle's simulator "
      "as the plant, a plant that shares no code with pamc's"};
  Options o;
  app.add_option("--cases", o.cases, "cases file holding the plant (e.g. tests/oracle/closed_loop_plant.json)")
      ->required()
      ->check(CLI::ExistingFile);
  app.add_option("--case", o.case_name, "the case that is the plant (default: the file's only case)");
  app.add_option("--model", o.model, "model file the controllers use instead of identifying one on u0")
      ->check(CLI::ExistingFile);
  app.add_option("--only", o.only,
                 "comma list of: table1, table2, triangle, discontinuous, payload (as pamc experiments)")
      ->delimiter(',');
  app.add_option("--out-dir", o.out_dir, "output folder (CSVs, summary.txt, summary.json)")->capture_default_str();
  app.add_flag("--no-figures", o.no_figures, "skip the PNG figures");
  app.add_option("--mbc-horizon", o.mbc_horizon, "MBC: samples ahead its inverse aims at; 0 = automatic (as pamc's)")
      ->capture_default_str()
      ->check(CLI::Range(0, 2000));
  app.add_option("--mbc-pace-share", o.mbc_pace_share,
                 "MBC: the setpoint governor's limits lowered to this share of a slower model's pace (as pamc's)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  app.add_option("--mbc-rate", o.mbc_rate, "MBC: the setpoint governor's rate [mm/s]; 0: none (as pamc's)")
      ->capture_default_str()
      ->check(CLI::NonNegativeNumber);
  app.add_option("--mbc-accel", o.mbc_accel, "MBC: the setpoint governor's acceleration [mm/s^2] (as pamc's)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  app.add_option("--mbc-accel-carried", o.mbc_accel_carried,
                 "MBC: the governor's acceleration [mm/s^2] while the model carries the loop (as pamc's)")
      ->capture_default_str()
      ->check(CLI::PositiveNumber);
  CLI11_PARSE(app, argc, argv);
  try {
    return run(o);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pamc_oracle_experiments: %s\n", e.what());
    return 1;
  }
}
