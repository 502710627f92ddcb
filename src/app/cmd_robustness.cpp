#include "app/command.hpp"

#include <chrono>
#include <algorithm>
#include <cstdio>
#include <iterator>

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
    cmd_->add_option("--only-axes", only_axes_,
                     "comma list of the axes to run: flow, mass, supply, noise, model "
                     "(default: all; the grid needs two)");
    cmd_->add_option("--seed", seed_, "GA seed of the identifications")->capture_default_str();
    cmd_->add_option("--method", method_,
                     "the identifications' fit: ga (the paper's GA first) or lm (spread starts, fast)")
        ->capture_default_str()
        ->check(CLI::IsMember({"lm", "ga"}));
    cmd_->add_option("--duration-scale", duration_scale_,
                     "the trajectories' durations times this (a quick look; 1: the experiments' durations)")
        ->capture_default_str()
        ->check(CLI::Range(0.01, 1.0));
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
    addParts();
    ctrl_.add(cmd_);
    cmd_->get_option("--model")->description(
        "the nominal model (JSON) instead of identifying one on u0 of the nominal plant");
  }

  int run() override {
    if (!merge_.empty()) return merge();
    if (!pairs_of_.empty()) return pairs();
    if (!shard_.empty()) return axesPart();
    const auto rep = sim::runRobustness(settings());
    std::printf("\n%s", rep.text.c_str());
    std::printf("results in %s/ (axis_*.csv, grid.csv, *.png heat maps, summary.txt, summary.json); %.1f s\n",
                out_.c_str(), rep.seconds);
    return 0;
  }

 private:
  // The parts of a sweep on several machines (docs/PERFORMANCE.md, "Sweeps in parts").
  void addParts() {
    cmd_->add_option(
        "--shard", shard_,
        "run only part I of N of the phase's cells (I/N, e.g. 2/4) and write them to --out-dir/cells.json; "
        "every part with the same options, then --merge");
    auto* pairs = cmd_->add_option("--pairs-of", pairs_of_,
                                   "the second phase: the pairs grid chosen from the axes merged in this folder, with "
                                   "its settings (give only --shard, --out-dir, --threads)");
    auto* merge = cmd_->add_option("--merge", merge_,
                                   "combine the cells.json of these folders (every part of one phase) into the files "
                                   "one run writes, in --out-dir");
    merge->excludes(pairs)->excludes(cmd_->get_option("--shard"));
  }

  // With --pairs-of or --merge the settings are the cells'; an option that would set them is refused.
  void refuseSettings(const char* mode) const {
    static const char* const kAllowed[] = {"--shard",   "--pairs-of", "--merge",
                                           "--out-dir", "--threads",  "--no-figures"};
    for (const auto* o : cmd_->get_options()) {
      if (o->count() == 0 || o->get_name().rfind("--", 0) != 0) continue;
      const std::string name = o->get_name();
      if (std::find(std::begin(kAllowed), std::end(kAllowed), name) == std::end(kAllowed))
        throw CLI::ValidationError(name, std::string("the settings are those of the cells ") + mode +
                                             " reads; give them to the first phase's parts");
    }
  }

  int axesPart() {
    sim::RobustnessSettings s = settings();
    s.shard = sim::parseShard(shard_);
    const auto doc = sim::runRobustnessCells(s);
    std::printf("part %s of the axes: %zu cells in %s/cells.json\n", shard_.c_str(), doc.at("cells").size(),
                out_.c_str());
    std::printf("when all %d parts are done: pamc robustness --merge DIR1 ... DIR%d --out-dir DIR\n", s.shard.count,
                s.shard.count);
    return 0;
  }

  int pairs() {
    refuseSettings("--pairs-of");
    sim::RobustnessSettings s;
    s.out_dir = out_, s.threads = threads_, s.log = progressLine;
    if (!shard_.empty()) s.shard = sim::parseShard(shard_);
    const auto axes = sim::readRobustnessCells(pairs_of_);
    const auto doc = sim::runRobustnessCells(s, &axes);
    std::printf("part %d/%d of the pairs grid: %zu cells (with the axes') in %s/cells.json\n", s.shard.index,
                s.shard.count, doc.at("cells").size(), out_.c_str());
    std::printf("when all %d parts are done: pamc robustness --merge DIR1 ... DIR%d --out-dir %s\n", s.shard.count,
                s.shard.count, pairs_of_.c_str());
    return 0;
  }

  int merge() {
    refuseSettings("--merge");
    std::vector<nlohmann::json> docs;
    for (const auto& dir : merge_) docs.push_back(sim::readRobustnessCells(dir));
    sim::RobustnessSettings out;
    out.out_dir = out_, out.figures = !no_figures_, out.log = progressLine;
    const auto rep = sim::mergeRobustness(docs, out);
    std::printf("\n%s", rep.text.c_str());
    std::printf("results in %s/ from %zu parts\n", out_.c_str(), docs.size());
    if (rep.pairs_pending)
      std::printf(
          "next, the pairs grid %s x %s: pamc robustness --pairs-of %s --shard I/N --out-dir PART_I, then "
          "pamc robustness --merge PART_1 ... PART_N --out-dir %s\n",
          rep.strongest[0].c_str(), rep.strongest[1].c_str(), out_.c_str(), out_.c_str());
    return 0;
  }

  sim::RobustnessSettings settings() const {
    sim::RobustnessSettings s;
    if (!plant_.empty()) s.plant = plant::PlantConfig::fromFile(plant_);
    s.out_dir = out_;
    s.model_file = ctrl_.model_file;
    s.only_axes = splitList(only_axes_);
    s.fit = ident::FitSettings::forMethod(ident::fitMethodFromString(method_));
    s.fit.ga.seed = seed_;
    s.duration_scale = duration_scale_;
    s.threads = threads_;
    s.grid = !no_grid_;
    s.common_window = score_from_ == "common";
    s.figures = !no_figures_;
    s.ctrl = ctrl_.paperConfig();
    s.log = progressLine;
    return s;
  }

  std::string out_ = "robustness", plant_, only_axes_, score_from_ = "common", shard_, pairs_of_, method_ = "ga";
  double duration_scale_ = 1.0;
  std::vector<std::string> merge_;
  std::uint64_t seed_ = 1;
  int threads_ = 2;
  bool no_grid_ = false, no_figures_ = false;
  ControllerOptions ctrl_;
};

}  // namespace

std::unique_ptr<Command> makeRobustnessCommand(CLI::App& app) { return std::make_unique<RobustnessCommand>(app); }

}  // namespace pamc::app
