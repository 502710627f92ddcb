// pamc calibrate: the protocol of docs/CALIBRATION.md. The physics plant's free parameters and the
// reading of ki are fitted to the calibrated claims (Table 1 and Table 2's triangle row) by a coordinate
// search; the table shows every point tried beside the paper's figures, the chosen one in bold.
#include "app/command.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "io/measurement.hpp"
#include "io/text.hpp"
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

std::string axesText() {
  std::string t;
  for (const auto& a : sim::calibrationAxes()) {
    t += "  " + a.name + " [" + a.unit + "]: " + a.physics + "; tries";
    for (double v : a.values) t += " " + io::fmt("%g", v);
    t += "\n";
  }
  return t;
}

class CalibrateCommand final : public Command {
 public:
  explicit CalibrateCommand(CLI::App& app)
      : Command(app.add_subcommand("calibrate",
                                   "fit the physics plant's free parameters and the reading of ki to what the paper "
                                   "tuned on (Table 1 and Table 2's triangle row) - nothing else; prints every point "
                                   "tried (docs/CALIBRATION.md)")) {
    cmd_->footer("Free parameters (one at a time, the best kept, --passes times over):\n" + axesText());
    cmd_->add_option("--ki-grid", ki_, "comma list of PI integral gains to try [V/(mm s)] (0.15: as printed)")
        ->capture_default_str();
    cmd_->add_option("--passes", passes_, "passes of the coordinate search over the free parameters")
        ->capture_default_str()
        ->check(CLI::Range(1, 5));
    cmd_->add_option("--axes", axes_,
                     "comma list of the free parameters to search (default: all; the others stay "
                     "at their nominal values)");
    cmd_->add_option("--threads", threads_, "plants evaluated at once")
        ->capture_default_str()
        ->check(CLI::Range(1, 64));
    cmd_->add_option("--out-dir", work_, "directory for every point's runs")->capture_default_str();
    cmd_->add_option("--out", out_, "also write the table (Markdown) to this file");
  }

  int run() override {
    sim::CalibrationSettings s;
    s.ki_grid = numbers("--ki-grid", ki_);
    s.passes = passes_;
    s.threads = threads_;
    s.axes = splitList(axes_);
    s.work_dir = work_;
    s.log = [](const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); };
    const auto t0 = std::chrono::steady_clock::now();
    const auto r = sim::runCalibration(s);
    const std::string table = sim::formatCalibration(r);
    std::printf("%s\n", table.c_str());
    const auto& best = r.tried[r.best];
    std::printf("Chosen:");
    for (size_t i = 0; i < sim::calibrationAxes().size(); ++i)
      std::printf(" %s %g,", sim::calibrationAxes()[i].name.c_str(), best.reading.plant_values[i]);
    std::printf(" ki %g - distance %.3f (mean |ln(pamc / paper)| over the calibrated claims)\n", best.reading.ki,
                best.distance);
    if (!out_.empty()) io::writeFileAtomic(out_, table);
    std::printf("%zu points in %.0f s; every run in %s/\n", r.tried.size(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), work_.c_str());
    return 0;
  }

 private:
  std::string ki_ = "0.15,0.5,1,1.3,1.5,1.7,2,2.5,3,4";
  int passes_ = 2, threads_ = 2;
  std::string out_, work_ = "calibration", axes_;
};

}  // namespace

std::unique_ptr<Command> makeCalibrateCommand(CLI::App& app) { return std::make_unique<CalibrateCommand>(app); }

}  // namespace pamc::app
