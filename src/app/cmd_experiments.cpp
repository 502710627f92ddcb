#include "app/command.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "app/controller_options.hpp"
#include "plant/plant.hpp"
#include "sim/experiments.hpp"
#include "sim/paper_claims.hpp"

namespace pamc::app {
namespace {

// pamc experiments: the paper's experiments on the emulator (docs/EXPERIMENTS.md).
class ExperimentsCommand final : public Command {
 public:
  explicit ExperimentsCommand(CLI::App& app)
      : Command(app.add_subcommand("experiments",
                                   "run the paper's experiments on the calibrated physics plant (Tables 1 "
                                   "and 2, square/sawtooth, payload step); judge every claim of the paper; "
                                   "write CSVs, figures and a summary")) {
    cmd_->add_option("--out-dir", out_, "output folder (CSVs, figures, summary.txt, summary.json)")
        ->capture_default_str();
    addOldSpelling(cmd_, "--out", "--out-dir", out_);
    cmd_->add_option("--plant", plant_, "plant emulator config (JSON; see `pamc plant`)");
    cmd_->add_option("--only", only_,
                     "comma list of: table1, table2, triangle (Table 2's triangle row alone), discontinuous, payload "
                     "(table1 always runs)");
    cmd_->add_option("--seed", seed_, "GA seed")->capture_default_str();
    cmd_->add_flag("--no-figures", nofig_, "skip the PNG figures");
    cmd_->add_flag("--list-claims", list_claims_,
                   "print the table of the paper's claims with their thresholds (Markdown) and exit");
    cmd_->add_option("--sine-start", sine_start_,
                     "where Table 2's sines start: 'centre' (rising, from the muscle parked at 0.2 mm, scored from the "
                     "first reach: the paper's start transient) or 'trough' (where the muscle is parked: none)")
        ->capture_default_str()
        ->check(CLI::IsMember({"centre", "trough"}));
    ctrl_.add(cmd_);
    cmd_->get_option("--model")->description("use this model file instead of identifying one on u0");
  }
  int run() override {
    if (list_claims_) {
      std::printf("%s", sim::claimsMarkdown().c_str());
      return 0;
    }
    sim::ExperimentSettings s;
    if (!plant_.empty()) {
      s.plant = plant::PlantConfig::fromFile(plant_);
      s.calibrated_on = "not calibrated: the plant of " + plant_;
    }
    s.out_dir = out_;
    s.model_file = ctrl_.model_file;
    s.figures = !nofig_;
    s.sine_start = sine_start_ == "trough" ? sim::SineStart::Trough : sim::SineStart::Centre;
    s.only = splitList(only_);  // runExperiments refuses an unknown name
    s.fit.ga.seed = seed_;
    s.ctrl = ctrl_.paperConfig();  // the experiments read the model themselves (Table 1 reports on it)
    s.log = progressLine;
    const auto t0 = std::chrono::steady_clock::now();
    const auto rep = sim::runExperiments(s);
    std::printf("\n%s", rep.text.c_str());
    std::printf("results in %s/ (CSV per run, PNG figures, summary.txt, summary.json); %.1f s\n", out_.c_str(),
                std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    return 0;
  }

 private:
  std::string out_ = "results", plant_, only_, sine_start_ = "centre";
  bool nofig_ = false, list_claims_ = false;
  std::uint64_t seed_ = 1;
  ControllerOptions ctrl_;
};

}  // namespace

std::unique_ptr<Command> makeExperimentsCommand(CLI::App& app) { return std::make_unique<ExperimentsCommand>(app); }

}  // namespace pamc::app
