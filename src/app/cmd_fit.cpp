#include "app/command.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

#include "ident/identify.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"

namespace pamc::app {
namespace {

// pamc fit: identify a model (the Bouc-Wen core plus chosen effects) from a measurement.
class FitCommand final : public Command {
 public:
  explicit FitCommand(CLI::App& app)
      : Command(app.add_subcommand("fit",
                                   "identify a model from a measurement CSV (t,u,y[,load,...]) by "
                                   "Levenberg-Marquardt from spread starts (or the paper's GA) and Nelder-Mead")) {
    cmd_->add_option("data", data_, "measurement CSV with header t,u,y")->required();
    cmd_->add_option("--out", out_, "model file (JSON) to write");
    cmd_->add_option("--effects", effects_, "comma list of effects to add to the Bouc-Wen core (see `pamc effects`)");
    cmd_->add_option(
            "--start", start_,
            "model file (JSON) to start from: its effects join the structure, its parameters start the "
            "search, the search's box widened to hold them (refit a model on a new record, or add --effects to it)")
        ->check(CLI::ExistingFile);
    cmd_->add_option("--method", method_,
                     "lm: Levenberg-Marquardt from spread starts (fast); ga: the paper's genetic algorithm first; "
                     "auto: lm for the plain Bouc-Wen model, ga when effects are added (see docs/PERFORMANCE.md)")
        ->capture_default_str()
        ->check(CLI::IsMember({"auto", "lm", "ga"}));
    cmd_->add_option("--seed", fs_.ga.seed, "seed of the GA and of the spread starts (same seed, same result)")
        ->capture_default_str();
    cmd_->add_option("--population", fs_.ga.population, "GA population (--method ga)")
        ->capture_default_str()
        ->check(CLI::Range(4, 10000));
    cmd_->add_option("--generations", fs_.ga.max_generations, "GA generation limit (--method ga)")
        ->capture_default_str()
        ->check(CLI::Range(1, 100000));
    cmd_->add_option("--threads", fs_.ga.threads, "worker threads (0: all cores)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1024));
    addOutputFormOption(cmd_, form_);
    cmd_->add_flag("--quiet", quiet_, "no progress on stderr");
  }
  int run() override {
    const std::string& data = data_;
    const std::string& out = out_;
    const std::string& effects = effects_;
    const bool quiet = quiet_;
    std::vector<std::string> warnings;
    io::Measurement m = io::readMeasurementCsv(data, &warnings);
    printWarnings(warnings);
    model::Model structure;
    structure.setOutputForm(outputFormOf(form_));
    std::optional<model::Model> start;
    if (!start_.empty()) {
      start = io::readModelFile(start_);
      structure.setOutputForm(start->outputForm());
      for (int i = 0; i < start->numEffects(); ++i) structure.addEffect(start->effect(i).name());
    }
    for (const auto& e : splitList(effects))
      if (!structure.hasEffect(e)) structure.addEffect(e);
    ident::FitSettings fs = ident::FitSettings::forMethod(method_ == "auto" ? ident::autoFitMethod(structure)
                                                                            : ident::fitMethodFromString(method_));
    fs.ga = fs_.ga;
    fs.box_holds_start = true;
    if (!quiet)
      std::fprintf(stderr, "fitting %s (%d parameters) to %zu samples of %s, Ts = %g s\n", structure.describe().c_str(),
                   structure.numParams() - 1, m.size(), data.c_str(), m.Ts);
    int last = 0;
    const auto r = ident::fit(
        structure, m, fs,
        [&](const char* stage, int it, double rmse) {
          if (quiet) return;
          if (std::string(stage) == "ga" && (it == 1 || it - last >= 10)) {
            last = it;
            std::fprintf(stderr, "  GA generation %4d  best RMSE %.6g\n", it, rmse);
          } else if (std::string(stage) == "refine") {
            std::fprintf(stderr, "  refined  RMSE %.6g\n", rmse);
          }
        },
        start ? &*start : nullptr);
    for (const auto& w : r.widened)
      std::fprintf(stderr, "note: the start's %s: the search's box was widened to hold it\n", w.c_str());
    const auto specs = r.model.paramSpecs();
    const auto p = r.model.params();
    std::printf("model: %s\n", r.model.describe().c_str());
    for (size_t i = 0; i < specs.size(); ++i)
      std::printf("  %-28s = %-14.8g %s%s\n", specs[i].name.c_str(), p[i], specs[i].unit.c_str(),
                  specs[i].name == "alpha" ? "  (fixed: scale of h)" : "");
    const auto& c = r.model.core();
    std::printf("  (gain of u: k rho = %.6g; gain of h: k (1 - rho) = %.6g)\n", c.k * c.rho, c.k * (1 - c.rho));
    std::printf("RMSE %.6g (MSE %.6g) over %zu samples\n", r.rmse, r.mse, m.size());
    if (fs.method == ident::FitMethod::Ga)
      std::printf("%d generations, %d evaluations, %.2f s wall time\n", r.generations, r.evaluations, r.seconds);
    else
      std::printf("method lm, %d evaluations, %.2f s wall time\n", r.evaluations, r.seconds);
    if (!out.empty()) {
      io::writeModelFile(out, r.model, ident::fitReport(r, fs, m, data));
      std::printf("wrote %s\n", out.c_str());
    }
    return 0;
  }

 private:
  std::string data_, out_, effects_, start_, method_ = "auto";
  ident::FitSettings fs_;
  bool quiet_ = false;
  std::string form_ = "aligned";
};

}  // namespace

std::unique_ptr<Command> makeFitCommand(CLI::App& app) { return std::make_unique<FitCommand>(app); }

}  // namespace pamc::app
