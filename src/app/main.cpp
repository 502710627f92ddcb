// pamc: command-line front end.
#include <CLI/CLI.hpp>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "app/bus_commands.hpp"
#include "app/cmd_calibrate.hpp"
#include "diagnose/compare.hpp"
#include "diagnose/diagnose.hpp"
#include "ident/identify.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "model/effect.hpp"
#include "plant/plant.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"
#include "sim/trajectory.hpp"

namespace {

std::vector<std::string> splitList(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string p;
  while (std::getline(ss, p, ','))
    if (!p.empty()) out.push_back(p);
  return out;
}

void progressLine(const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); }

int cmdFit(const std::string& data, const std::string& out, const std::string& effects, const pamc::ident::FitSettings& fs,
           bool quiet) {
  pamc::io::Measurement m = pamc::io::readMeasurementCsv(data);
  if (!m.warning.empty()) std::fprintf(stderr, "warning: %s\n", m.warning.c_str());
  pamc::model::Model structure;
  for (const auto& e : splitList(effects)) structure.addEffect(e);
  if (!quiet)
    std::fprintf(stderr, "fitting %s (%d parameters) to %zu samples of %s, Ts = %g s\n", structure.describe().c_str(),
                 structure.numParams() - 1, m.size(), data.c_str(), m.Ts);
  int last = 0;
  const auto r = pamc::ident::fit(structure, m, fs, [&](const char* stage, int it, double rmse) {
    if (quiet) return;
    if (std::string(stage) == "ga" && (it == 1 || it - last >= 10)) {
      last = it;
      std::fprintf(stderr, "  GA generation %4d  best RMSE %.6g\n", it, rmse);
    } else if (std::string(stage) == "refine") {
      std::fprintf(stderr, "  refined (Nelder-Mead)  RMSE %.6g\n", rmse);
    }
  });
  const auto specs = r.model.paramSpecs();
  const auto p = r.model.params();
  std::printf("model: %s\n", r.model.describe().c_str());
  for (size_t i = 0; i < specs.size(); ++i)
    std::printf("  %-28s = %-14.8g %s%s\n", specs[i].name.c_str(), p[i], specs[i].unit.c_str(),
                specs[i].name == "alpha" ? "  (fixed: scale of h)" : "");
  const auto& c = r.model.core();
  std::printf("  (gain of u: k rho = %.6g; gain of h: k (1 - rho) = %.6g)\n", c.k * c.rho, c.k * (1 - c.rho));
  std::printf("RMSE %.6g (MSE %.6g) over %zu samples\n", r.rmse, r.mse, m.size());
  std::printf("%d generations, %d evaluations, %.2f s wall time\n", r.generations, r.evaluations, r.seconds);
  if (!out.empty()) {
    pamc::io::writeModelFile(out, r.model,
                             {{"data", data}, {"samples", m.size()}, {"Ts", m.Ts}, {"rmse", r.rmse},
                              {"generations", r.generations}, {"evaluations", r.evaluations},
                              {"seconds", r.seconds}, {"seed", fs.ga.seed}});
    std::printf("wrote %s\n", out.c_str());
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"pamc - pneumatic artificial muscle control: Bouc-Wen model, GA identification, UKF active "
               "model control, plant emulator"};
  app.require_subcommand(1);

  // experiments
  auto* ex = app.add_subcommand("experiments", "run the paper's experiments on the plant emulator (Tables 1 and 2, "
                                               "square/sawtooth, payload step); write CSVs, figures and a summary");
  std::string ex_out = "results", ex_plant, ex_model, ex_only;
  bool ex_nofig = false;
  std::uint64_t ex_seed = 1;
  ex->add_option("--out", ex_out, "output directory")->capture_default_str();
  ex->add_option("--plant", ex_plant, "plant emulator config (JSON; see `pamc plant --dump`)");
  ex->add_option("--model", ex_model, "use this model file instead of identifying one on u0");
  ex->add_option("--only", ex_only, "comma list of: table1, table2, discontinuous, payload (table1 always runs)");
  ex->add_option("--seed", ex_seed, "GA seed")->capture_default_str();
  ex->add_flag("--no-figures", ex_nofig, "skip the PNG figures");
  pamc::control::ControllerConfig ex_cc;
  std::string ex_amc_form = "printed";
  ex->add_option("--kp", ex_cc.kp, "PI proportional gain [V/mm]")->capture_default_str()->check(CLI::NonNegativeNumber);
  ex->add_option("--ki", ex_cc.ki, "PI integral gain [V/(mm s)]")->capture_default_str()->check(CLI::NonNegativeNumber);
  ex->add_option("--kc", ex_cc.kc, "AMC compensation gain [V/mm]")->capture_default_str()->check(CLI::NonNegativeNumber);
  ex->add_option("--amc-horizon", ex_cc.amc_horizon, "AMC prediction horizon [samples]; 1 = eq. (17), 0 = automatic (bus delay + the model's response time)")->capture_default_str()->check(CLI::Range(0, 2000));
  ex->add_option("--eso-delta", ex_cc.delta, "ESO fal() linear zone delta [mm]")->capture_default_str()->check(CLI::PositiveNumber);
  ex->add_option("--eso-beta1", ex_cc.beta1, "ESO gain beta1")->capture_default_str();
  ex->add_option("--eso-beta2", ex_cc.beta2, "ESO gain beta2")->capture_default_str();
  ex->add_option("--eso-beta3", ex_cc.beta3, "ESO gain beta3")->capture_default_str();
  ex->add_option("--amc-form", ex_amc_form, "eq. (17): 'printed' predicts Y_{k+1} from the nominal command itself (the paper); 'increment' adds the model's one-step increment to the posterior output")->capture_default_str()->check(CLI::IsMember({"printed", "increment"}));
  ex->add_option("--amc-inverse", ex_cc.amc_inverse, "predictive AMC: fraction of the predicted error at the horizon corrected through the model's response (0: the paper's kc e_hat)")->capture_default_str()->check(CLI::Range(0.0, 1.0));
  ex->add_option("--eso-b0", ex_cc.b0, "ESO input gain b0 [mm/(s^2 V)]")->capture_default_str()->check(CLI::PositiveNumber);
  ex->add_option("--delay", ex_cc.delay_cycles, "cycles from command to the measurement that shows it, beyond one sample (2 on the CAN bus)")->capture_default_str()->check(CLI::Range(0, 7));

  // fit
  auto* fit = app.add_subcommand("fit", "identify a model from a measurement CSV (t,u,y[,load,...]) by GA + Nelder-Mead");
  std::string fit_data, fit_out, fit_effects;
  pamc::ident::FitSettings fs;
  bool fit_quiet = false;
  fit->add_option("data", fit_data, "measurement CSV with header t,u,y")->required();
  fit->add_option("--out", fit_out, "write the model file (JSON) here");
  fit->add_option("--effects", fit_effects, "comma list of effects to add to the Bouc-Wen core (see `pamc effects`)");
  fit->add_option("--seed", fs.ga.seed, "GA seed (same seed, same result)")->capture_default_str();
  fit->add_option("--population", fs.ga.population, "GA population")->capture_default_str()->check(CLI::Range(4, 10000));
  fit->add_option("--generations", fs.ga.max_generations, "GA generation limit")->capture_default_str()->check(CLI::Range(1, 100000));
  fit->add_option("--threads", fs.ga.threads, "worker threads (0: all cores)")->capture_default_str()->check(CLI::Range(0, 1024));
  fit->add_flag("--quiet", fit_quiet, "no progress on stderr");

  // emulate
  auto* em = app.add_subcommand("emulate", "excite the plant emulator open loop and write a measurement CSV");
  std::string em_input = "sine:0.1:0.2:2.9", em_out, em_plant;
  double em_duration = 40.0;
  em->add_option("--input", em_input, "command u(t) [V]: sine:F:OFFSET:AMP, triangle:F:LO:HI, square:F:LO:HI, chirp:F0:F1:OFFSET:AMP:DURATION, random:SEED:LO:HI, ...")
      ->capture_default_str();
  em->add_option("--duration", em_duration, "seconds")->capture_default_str()->check(CLI::PositiveNumber);
  em->add_option("--plant", em_plant, "plant emulator config (JSON)");
  std::string em_load;
  em->add_option("--load", em_load, "external force [N] over time, same forms as --input (adds a 'load' column)");
  em->add_option("--out", em_out, "CSV to write (t,u,y,p)")->required();

  // plant
  auto* pl = app.add_subcommand("plant", "show the plant emulator's configuration");
  std::string pl_file;
  pl->add_option("--config", pl_file, "config file to load and show merged with the defaults");

  // effects
  auto* ef = app.add_subcommand("effects", "list the catalogue of physical effects");

  // compare
  auto* cmp = app.add_subcommand("compare", "simulate a model on a measurement's input and show where it fails: "
                                            "RMSE, max error, fit %, error by where it happens, residual tests, figures");
  std::string cmp_model, cmp_data, cmp_report, cmp_json;
  cmp->add_option("model", cmp_model, "model file (JSON, from `pamc fit` or `pamc diagnose`)")->required();
  cmp->add_option("data", cmp_data, "measurement CSV with header t,u,y")->required();
  cmp->add_option("--report", cmp_report, "directory for CSVs and figures (default: DATA.compare/)");
  cmp->add_option("--json", cmp_json, "write the numbers as JSON here");

  // diagnose
  auto* dg = app.add_subcommand("diagnose", "fit the reference model, find which physical effect is missing, add it, "
                                            "refit, and repeat while the validated error falls");
  std::string dg_data, dg_val, dg_report, dg_json, dg_cands;
  pamc::diagnose::DiagnoseSettings ds;
  dg->add_option("data", dg_data, "training measurement CSV (t,u,y[,load,...])")->required();
  dg->add_option("--validate", dg_val, "validation measurement (default: hold out the last part of DATA)");
  dg->add_option("--holdout", ds.holdout, "fraction held out without --validate")->capture_default_str()->check(CLI::Range(0.06, 0.94));
  dg->add_option("--max-effects", ds.max_effects, "at most this many effects added")->capture_default_str()->check(CLI::Range(0, 9));
  dg->add_option("--min-gain", ds.min_gain, "an effect must lower the validated RMSE by this fraction")->capture_default_str()->check(CLI::Range(0.0, 0.99));
  dg->add_option("--candidates", dg_cands, "comma list of effects to try (default: the whole catalogue)");
  dg->add_option("--report", dg_report, "directory for figures, CSVs and the final model");
  dg->add_option("--json", dg_json, "write the result as JSON here");
  dg->add_option("--seed", ds.seed, "seed of the searches")->capture_default_str();
  dg->add_option("--threads", ds.threads, "worker threads (0: all cores)")->capture_default_str()->check(CLI::Range(0, 1024));

  pamc::app::BusCommands bus(app);
  pamc::app::CalibrateCommand calibrate(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }

  try {
    if (const int rc = bus.run(); rc >= 0) return rc;
    if (calibrate.selected()) return calibrate.run();
    if (*ex) {
      pamc::sim::ExperimentSettings s;
      if (!ex_plant.empty()) s.plant = pamc::plant::PlantConfig::fromFile(ex_plant);
      s.out_dir = ex_out;
      s.model_file = ex_model;
      s.figures = !ex_nofig;
      s.only = splitList(ex_only);
      for (const auto& o : s.only)
        if (o != "table1" && o != "table2" && o != "discontinuous" && o != "payload")
          throw std::invalid_argument("--only: unknown experiment '" + o + "' (known: table1, table2, discontinuous, payload)");
      s.fit.ga.seed = ex_seed;
      s.ctrl = ex_cc;
      s.ctrl.amc_as_printed = ex_amc_form == "printed";
      s.log = progressLine;
      const auto t0 = std::chrono::steady_clock::now();
      const auto rep = pamc::sim::runExperiments(s);
      std::printf("\n%s", rep.text.c_str());
      std::printf("results in %s/ (CSV per run, PNG figures, summary.txt, summary.json); %.1f s\n", ex_out.c_str(),
                  std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
      return 0;
    }
    if (*fit) return cmdFit(fit_data, fit_out, fit_effects, fs, fit_quiet);
    if (*em) {
      pamc::plant::PlantConfig pc = em_plant.empty() ? pamc::plant::PlantConfig::defaults()
                                                     : pamc::plant::PlantConfig::fromFile(em_plant);
      pamc::plant::Plant p(pc);
      const auto traj = pamc::sim::Trajectory::parse(em_input);
      pamc::sim::Trajectory force;
      if (!em_load.empty()) force = pamc::sim::Trajectory::parse(em_load);
      const auto r = pamc::sim::runOpenLoopInput(p, traj, em_duration, em_load.empty() ? nullptr : &force);
      if (em_load.empty())
        pamc::io::writeCsvAtomic(em_out, {"t", "u", "y", "p"}, {&r.t, &r.u, &r.y, &r.p});
      else
        pamc::io::writeCsvAtomic(em_out, {"t", "u", "y", "p", "load"}, {&r.t, &r.u, &r.y, &r.p, &r.force});
      std::printf("wrote %s: %zu samples of u = %s\n", em_out.c_str(), r.t.size(), traj.describe().c_str());
      return 0;
    }
    if (*pl) {
      const auto c = pl_file.empty() ? pamc::plant::PlantConfig::defaults() : pamc::plant::PlantConfig::fromFile(pl_file);
      std::printf("%s\n", c.toJson().dump(2).c_str());
      return 0;
    }
    if (*cmp) {
      const auto m = pamc::io::readModelFile(cmp_model);
      const auto d = pamc::io::readMeasurementCsv(cmp_data);
      if (!d.warning.empty()) std::fprintf(stderr, "warning: %s\n", d.warning.c_str());
      const auto c = pamc::diagnose::compare(m, d);
      std::printf("model %s (%s) on %s: %zu samples, Ts = %g s\n", cmp_model.c_str(), m.describe().c_str(),
                  cmp_data.c_str(), d.size(), d.Ts);
      std::printf("%s", pamc::diagnose::formatReport(c.report).c_str());
      std::string dir = cmp_report.empty() ? cmp_data + ".compare" : cmp_report;
      std::string warn;
      pamc::diagnose::writeCompareReport(c, d, dir, warn);
      if (!warn.empty()) std::fprintf(stderr, "warning: %s\n", warn.c_str());
      std::printf("figures and CSVs in %s/\n", dir.c_str());
      if (!cmp_json.empty()) pamc::io::writeFileAtomic(cmp_json, pamc::diagnose::toJson(c).dump(2) + "\n");
      return 0;
    }
    if (*dg) {
      const auto d = pamc::io::readMeasurementCsv(dg_data);
      if (!d.warning.empty()) std::fprintf(stderr, "warning: %s\n", d.warning.c_str());
      pamc::io::Measurement v;
      if (!dg_val.empty()) {
        v = pamc::io::readMeasurementCsv(dg_val);
        if (!v.warning.empty()) std::fprintf(stderr, "warning: %s\n", v.warning.c_str());
      }
      ds.candidates = splitList(dg_cands);
      for (const auto& c : ds.candidates) (void)pamc::model::makeEffect(c);
      ds.log = progressLine;
      const auto r = pamc::diagnose::diagnose(d, dg_val.empty() ? nullptr : &v, ds);
      std::printf("\nFirst round (on top of the reference model), best first:\n");
      if (!r.rounds.empty())
        for (const auto& c : r.rounds.front())
          std::printf("  %-20s validation RMSE %-10.5g train %-10.5g  %s\n", c.effect.c_str(), c.rmse_val, c.rmse_train,
                      c.evidence.text.c_str());
      std::printf("\nLadder (validation: %s):\n", r.validation.c_str());
      for (const auto& g : r.ladder) {
        std::string e;
        for (const auto& x : g.effects) e += (e.empty() ? "" : " + ") + x;
        std::printf("  %-50s train %-10.5g validation %-10.5g\n", e.empty() ? "reference model" : ("+ " + e).c_str(),
                    g.rmse_train, g.rmse_val);
      }
      std::printf("\n%s\n", r.verdict.c_str());
      std::printf("%.1f s\n", r.seconds);
      if (!dg_report.empty()) {
        std::string warn;
        pamc::diagnose::writeReport(r, d, dg_val.empty() ? nullptr : &v, ds, dg_report, warn);
        if (!warn.empty()) std::fprintf(stderr, "warning: %s\n", warn.c_str());
        std::printf("report in %s/ (ladder.png, validation.png, residual_tests.png, model.json)\n", dg_report.c_str());
      }
      if (!dg_json.empty()) pamc::io::writeFileAtomic(dg_json, pamc::diagnose::toJson(r).dump(2) + "\n");
      return 0;
    }
    if (*ef) {
      for (const auto& e : pamc::model::catalogue()) {
        auto x = e.make();
        std::printf("%-20s %s %s\n", e.name, x->stage() == pamc::model::Stage::Input ? "[input] " : "[output]",
                    x->explanation());
        for (const auto& p : x->params())
          std::printf("%-20s   %-12s default %-10g bounds [%g, %g] %s\n", "", p.name.c_str(), p.def, p.lo, p.hi,
                      p.unit.c_str());
      }
      return 0;
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pamc: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
