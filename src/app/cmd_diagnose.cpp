#include "app/command.hpp"

#include <cstdio>
#include <string>
#include <vector>

#include "diagnose/diagnose.hpp"
#include "io/measurement.hpp"
#include "model/effect.hpp"

namespace pamc::app {
namespace {

// The ladder so far, kept while diagnose runs (DiagnoseSettings::checkpoint): with --out-dir DIR the
// diagnosis so far (the schema of --json, with "partial") in DIR/diagnosis.partial.json and its last rung's
// model in DIR/model.partial.json; with --json FILE the diagnosis so far in FILE.partial. Each written
// whole or not at all; removed when the run ends and the final files are written.
class PartialFiles {
 public:
  PartialFiles(const std::string& dir, const std::string& json) {
    if (!dir.empty()) {
      io::makeDirectory(dir, "report directory");
      diagnosis_.push_back(dir + "/diagnosis.partial.json");
      model_ = dir + "/model.partial.json";
    }
    if (!json.empty()) diagnosis_.push_back(json + ".partial");
  }
  void write(const diagnose::DiagnoseResult& so_far, const std::string& after) {
    if (diagnosis_.empty()) return;
    auto j = diagnose::toJson(so_far);
    j["partial"] = {{"after", after}, {"seconds", so_far.seconds}};
    for (const auto& p : diagnosis_) io::writeFileAtomic(p, j.dump(2) + "\n");
    if (!model_.empty()) io::writeFileAtomic(model_, j["model"].dump(2) + "\n");
    if (!said_)
      progressLine("the ladder so far is kept in " + diagnosis_.front() +
                   (model_.empty() ? "" : " (its last rung's model in " + model_ + ")") + " until the run ends");
    said_ = true;
  }
  void remove() const {
    for (const auto& p : diagnosis_) std::remove(p.c_str());
    if (!model_.empty()) std::remove(model_.c_str());
  }

 private:
  std::vector<std::string> diagnosis_;
  std::string model_;
  bool said_ = false;
};

// pamc diagnose: which physical effect is missing; add it, refit, repeat (docs/MODELING.md).
class DiagnoseCommand final : public Command {
 public:
  explicit DiagnoseCommand(CLI::App& app)
      : Command(app.add_subcommand("diagnose",
                                   "fit the reference model, find which physical effect is missing, add "
                                   "it, refit, and repeat while the validated error falls")) {
    cmd_->add_option("data", dg_data, "training measurement CSV (t,u,y[,load,...])")->required();
    cmd_->add_option("--validate", dg_val, "validation measurement (default: hold out the last part of DATA)");
    cmd_->add_option("--holdout", ds.holdout, "fraction held out without --validate")
        ->capture_default_str()
        ->check(CLI::Range(0.06, 0.94));
    cmd_->add_option("--max-effects", ds.max_effects, "at most this many effects added")
        ->capture_default_str()
        ->check(CLI::Range(0, 9));
    cmd_->add_option("--min-gain", ds.min_gain, "an effect must lower the validated RMSE by this fraction")
        ->capture_default_str()
        ->check(CLI::Range(0.0, 0.99));
    cmd_->add_option("--candidates", dg_cands,
                     "comma list of effects to try, or of effects to leave out as -name (write --candidates=-name,...; "
                     "default: the whole catalogue)");
    cmd_->add_option("--out-dir", dg_report, "folder for figures, CSVs and the final model");
    addOldSpelling(cmd_, "--report", "--out-dir", dg_report);
    cmd_->add_option("--json", dg_json, "write the result as JSON to this file");
    cmd_->add_option("--seed", ds.seed, "seed of the searches")->capture_default_str();
    cmd_->add_option(
            "--method", dg_method,
            "how each fit searches: lm (Levenberg-Marquardt from starts around the current model, each round's best "
            "searched again by the GA) or ga (the paper's GA first for every fit: slower; docs/PERFORMANCE.md)")
        ->capture_default_str()
        ->check(CLI::IsMember({"lm", "ga"}));
    addOutputFormOption(cmd_, dg_form);
    cmd_->add_flag("--no-probes", dg_no_probes,
                   "do not try the probes when the catalogue leaves the error above the noise");
    cmd_->add_option("--threads", ds.threads, "worker threads (0: all cores)")
        ->capture_default_str()
        ->check(CLI::Range(0, 1024));
  }
  int run() override {
    std::vector<std::string> warnings;
    const auto d = io::readMeasurementCsv(dg_data, &warnings);
    io::Measurement v;
    if (!dg_val.empty()) {
      v = io::readMeasurementCsv(dg_val, &warnings);
    }
    printWarnings(warnings);
    ds.candidates = splitList(dg_cands);
    ds.method = ident::fitMethodFromString(dg_method);
    ds.log = progressLine;
    ds.probes = !dg_no_probes;
    ds.output_form = outputFormOf(dg_form);
    PartialFiles partial(dg_report, dg_json);
    ds.checkpoint = [&partial](const diagnose::DiagnoseResult& so_far, const std::string& after) {
      partial.write(so_far, after);
    };
    const auto r = diagnose::diagnose(d, dg_val.empty() ? nullptr : &v, ds);
    std::printf("\nFirst round (on top of the reference model), best first:\n");
    if (!r.rounds.empty())
      for (const auto& c : r.rounds.front())
        std::printf("  %-20s validation RMSE %-10.5g train %-10.5g  %s\n", c.effect.c_str(), c.rmse_val, c.rmse_train,
                    c.evidence.text.c_str());
    std::printf("\nLadder (validation: %s):\n", r.validation.c_str());
    for (const auto& g : r.ladder) {
      std::string e;
      for (const auto& x : g.effects) e += (e.empty() ? "" : " + ") + x;
      std::printf("  %-50s train %-10.5g validation %-10.5g%s\n", e.empty() ? "reference model" : ("+ " + e).c_str(),
                  g.rmse_train, g.rmse_val,
                  g.removed.empty()       ? ""
                  : g.replaced_by.empty() ? ("  (" + g.removed + " taken out)").c_str()
                  : g.refined             ? ("  (" + g.removed + " refined to " + g.replaced_by + ")").c_str()
                                          : ("  (" + g.removed + " replaced by " + g.replaced_by + ")").c_str());
    }
    if (r.probe_rung) {
      std::string e;
      for (const auto& x : r.probes.front().effectsWith(r.ladder.back().effects)) e += (e.empty() ? "+ " : " + ") + x;
      const auto& p = r.probes.front();
      std::printf("  %-50s train %-10.5g validation %-10.5g  (probe%s, not added)\n", e.c_str(), p.rmse_train,
                  p.rmse_val, p.replaces.empty() ? "" : (" in place of " + p.replaces).c_str());
    }
    if (!r.probes.empty()) {
      std::printf("\nProbes (on top of the final model, or \"for\" an effect: in its place), best first:\n");
      for (const auto& p : r.probes)
        std::printf("  %-14s validation RMSE %-10.5g explains %3.0f %%  at %s\n", p.label().c_str(), p.rmse_val,
                    100 * p.explains, p.regime.c_str());
    }
    std::printf("\n%s\n", r.verdict.c_str());
    std::printf("%.1f s\n", r.seconds);
    if (!dg_report.empty()) {
      diagnose::writeReport(r, d, dg_val.empty() ? nullptr : &v, ds, dg_report, &warnings);
      printWarnings(warnings);
      std::printf("report in %s/ (ladder.png, validation.png, residual_tests.png, spectrum.png%s, model.json%s)\n",
                  dg_report.c_str(), r.probes.empty() ? "" : ", probes.png", r.probe_rung ? ", probe_model.json" : "");
    }
    if (!dg_json.empty()) io::writeFileAtomic(dg_json, diagnose::toJson(r).dump(2) + "\n");
    partial.remove();
    return 0;
  }

 private:
  std::string dg_data, dg_val, dg_report, dg_json, dg_cands, dg_method = "lm";
  bool dg_no_probes = false;
  std::string dg_form = "aligned";
  diagnose::DiagnoseSettings ds;
};

}  // namespace

std::unique_ptr<Command> makeDiagnoseCommand(CLI::App& app) { return std::make_unique<DiagnoseCommand>(app); }

}  // namespace pamc::app
