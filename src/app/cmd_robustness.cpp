#include "app/command.hpp"

#include <chrono>
#include <cstdio>

#include "app/controller_options.hpp"
#include "plant/plant.hpp"
#include "sim/robustness.hpp"

namespace pamc::app {
namespace {

// pamc robustness: where the AMC helps beyond the paper (docs/EXPERIMENTS.md).
class RobustnessCommand final : public Command {
 public:
  explicit RobustnessCommand(CLI::App& app)
      : Command(app.add_subcommand(
            "robustness",
            "where the AMC helps beyond the paper: PI, PID+ESO and PI+AMC on Table 2's trajectories and the square "
            "wave over plant changes they were not tuned for (valve flow, payload mass, supply pressure, sensor "
            "noise, a model identified on another amplitude), one axis at a time and then the grid of the two "
            "axes that move the AMC/PI ratio most; writes CSVs and heat maps of the RMSE ratios AMC/PI and "
            "ESO/PI, summary.txt and summary.json")) {
    cmd_->add_option("--out-dir", out_, "output folder (created)")->capture_default_str();
    cmd_->add_option("--plant", plant_, "the nominal plant (JSON; see `pamc plant`); default: the experiments' plant");
    cmd_->add_option("--only-axes", only_axes_, "comma list of the axes to run: flow, mass, supply, noise, model "
                                                "(default: all; the grid needs two)");
    cmd_->add_option("--seed", seed_, "GA seed of the identifications")->capture_default_str();
    cmd_->add_option("--threads", threads_, "worker threads over the independent runs")
        ->capture_default_str()
        ->check(CLI::Range(1, 64));
    cmd_->add_option("--score-from", score_from_,
                     "where the sines (started away from home) are scored: 'common' - the four controllers over one "
                     "window, from the latest of their first reaches; 'own' - each from its own first reach (Table 2)")
        ->capture_default_str()
        ->check(CLI::IsMember({"common", "own"}));
    cmd_->add_flag("--no-pairs", no_grid_, "only the one-axis sweeps, no two-axis heat maps");
    addOldFlag(cmd_, "--no-grid", "robustness --no-pairs", no_grid_);
    cmd_->add_flag("--no-figures", no_figures_, "skip the PNG heat maps");
    ctrl_.add(cmd_);
    cmd_->get_option("--model")->description("the nominal model (JSON) instead of identifying one on u0 of the nominal plant");
  }

  int run() override {
    sim::RobustnessSettings s;
    if (!plant_.empty()) s.plant = plant::PlantConfig::fromFile(plant_);
    s.out_dir = out_;
    s.model_file = ctrl_.model_file;
    s.only_axes = splitList(only_axes_);
    s.fit.ga.seed = seed_;
    s.threads = threads_;
    s.grid = !no_grid_;
    s.common_window = score_from_ == "common";
    s.figures = !no_figures_;
    s.ctrl = ctrl_.paperConfig();
    s.log = progressLine;
    const auto rep = sim::runRobustness(s);
    std::printf("\n%s", rep.text.c_str());
    std::printf("results in %s/ (axis_*.csv, grid.csv, *.png heat maps, summary.txt, summary.json); %.1f s\n",
                out_.c_str(), rep.seconds);
    return 0;
  }

 private:
  std::string out_ = "robustness", plant_, only_axes_, score_from_ = "common";
  std::uint64_t seed_ = 1;
  int threads_ = 2;
  bool no_grid_ = false, no_figures_ = false;
  ControllerOptions ctrl_;
};

}  // namespace

std::unique_ptr<Command> makeRobustnessCommand(CLI::App& app) { return std::make_unique<RobustnessCommand>(app); }

}  // namespace pamc::app
