// pamc calibrate: the two-target calibration of docs/CALIBRATION.md. Every candidate (the
// emulator's pressure lag x the reading of ki x the reading of eq. 17) runs the paper's experiments;
// the table shows its Table 1 and Table 2 figures beside the paper's and how many of the paper's
// claims it reproduces, best first.
#include "app/command.hpp"

#include <cmath>
#include <string>

#include <chrono>
#include <cstdio>
#include <sstream>

#include "io/measurement.hpp"
#include "io/text.hpp"
#include "plant/plant.hpp"
#include "sim/calibration.hpp"

namespace pamc::app {

namespace {

std::vector<double> numbers(const std::string& flag, const std::string& s) {
  std::vector<double> v;
  std::stringstream ss(s);
  std::string p;
  while (std::getline(ss, p, ',')) {
    char* end = nullptr;
    const double d = std::strtod(p.c_str(), &end);
    if (p.empty() || *end != '\0' || !(d > 0) || !std::isfinite(d))
      throw std::invalid_argument(flag + ": '" + p + "' is not a positive number");
    v.push_back(d);
  }
  if (v.empty()) throw std::invalid_argument(flag + ": empty list");
  return v;
}

class CalibrateCommand final : public Command {
 public:
  explicit CalibrateCommand(CLI::App& app)
      : Command(app.add_subcommand("calibrate",
                                   "fit the emulator's pressure lag and the reading of the paper's gains to Table 1 "
                                   "and to the closed-loop results at once; prints the calibration table "
                                   "(docs/CALIBRATION.md)")) {
    cmd_->add_option("--lag", lag_, "comma list of pressure-lag time constants to try [s]")->capture_default_str();
    cmd_->add_option("--ki", ki_, "comma list of PI integral gains to try [V/(mm s)] (0.15: as printed)")->capture_default_str();
    cmd_->add_option("--forms", forms_, "eq. (17) readings to try: printed, increment (comma list)")->capture_default_str();
    cmd_->add_option("--eso-tau", eso_tau_, "comma list of first-order ESO time constants to try [s]")->capture_default_str();
    cmd_->add_option("--eso-wo", eso_wo_, "comma list of first-order ESO bandwidths to try [rad/s]")->capture_default_str();
    cmd_->add_option("--plant", plant_, "start from this plant file (JSON, \"kind\": \"model\") instead of the model plant's defaults");
    cmd_->add_option("--work", work_, "directory for every candidate's runs")->capture_default_str();
    cmd_->add_option("--out", out_, "also write the table (Markdown) to this file");
  }

  int run() override {
    sim::CalibrationSettings s;
    // The calibration varies the model plant's pressure lag (docs/CALIBRATION.md).
    s.base.plant = plant_.empty() ? plant::PlantConfig::modelDefaults() : plant::PlantConfig::fromFile(plant_);
    s.lag_tau_s = numbers("--lag", lag_);
    s.ki = numbers("--ki", ki_);
    s.eso_tau = numbers("--eso-tau", eso_tau_);
    s.eso_wo = numbers("--eso-wo", eso_wo_);
    std::stringstream ss(forms_);
    std::string f;
    while (std::getline(ss, f, ',')) {
      if (f == "printed") s.amc_as_printed.push_back(true);
      else if (f == "increment") s.amc_as_printed.push_back(false);
      else throw std::invalid_argument("--forms: unknown reading '" + f + "' (known: printed, increment)");
    }
    if (s.amc_as_printed.empty()) throw std::invalid_argument("--forms: empty list");
    s.work_dir = work_;
    s.log = [](const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); };
    const auto t0 = std::chrono::steady_clock::now();
    auto rows = sim::runCalibration(s);
    sim::rankCalibration(rows);
    const std::string table = sim::formatCalibration(rows, 0);
    std::printf("%s\n", table.c_str());
    if (!rows.empty()) {
      std::printf("Best: lag %g s, ki %g, eq. 17 %s, ESO tau %g s wo %g rad/s - %d/%zu of the paper's claims:\n%s",
                  rows[0].lag_tau_s, rows[0].ki, rows[0].amc_as_printed ? "as printed" : "as increment", rows[0].eso_tau,
                  rows[0].eso_wo, rows[0].met, rows[0].criteria.size(),
                  sim::formatCriteria(rows[0].criteria).c_str());
    }
    if (!out_.empty()) io::writeFileAtomic(out_, table);
    std::printf("%zu candidates in %.0f s; every run in %s/\n", rows.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), work_.c_str());
    return 0;
  }

 private:
  std::string lag_ = "0.04,0.1,0.15,0.2,0.25,0.3";
  std::string ki_ = "0.15,1.0,1.1,1.2,1.3";
  std::string forms_ = "printed,increment";
  std::string eso_tau_ = io::fmt("%g", control::ControllerConfig{}.eso_tau);  // the default alone
  std::string eso_wo_ = io::fmt("%g", control::ControllerConfig{}.eso_wo);
  std::string plant_, out_;
  std::string work_ = "calibration";
};

}  // namespace

std::unique_ptr<Command> makeCalibrateCommand(CLI::App& app) { return std::make_unique<CalibrateCommand>(app); }

}  // namespace pamc::app
