// The JSON and the report folder of a diagnosis: the ladder, the validation data against the reference
// and the final model, the residual tests, the probes, and their figures.
#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <stdexcept>

#include "diagnose/diagnosis.hpp"
#include "io/model_file.hpp"
#include "io/text.hpp"
#include "report/figures.hpp"

namespace pamc::diagnose {

using detail::join;
using detail::simulate;
using io::fmt;

nlohmann::json toJson(const DiagnoseResult& r) {
  nlohmann::json j;
  j["samples"] = r.samples;
  j["validation_samples"] = r.val_samples;
  j["validation"] = r.validation;
  j["baseline"] = {{"rmse_train", r.ladder.front().rmse_train}, {"rmse_val", r.ladder.front().rmse_val}};
  j["validation_offset"] = r.val_offset;  // mean of measured - final model there
  j["validation_offset_course"] = {{"first_tenth", r.val_offset_course.head},
                                   {"second_half", r.val_offset_course.tail}};
  nlohmann::json c = nlohmann::json::array();
  if (!r.rounds.empty())
    for (const auto& x : r.rounds.front())
      c.push_back({{"effect", x.effect},
                   {"rmse_val", x.rmse_val},
                   {"rmse_train", x.rmse_train},
                   {"evidence", x.evidence.text},
                   {"evidence_strength", x.evidence.strength}});
  j["candidates"] = c;
  nlohmann::json l = nlohmann::json::array();
  for (const auto& g : r.ladder) {
    l.push_back({{"effects", g.effects}, {"rmse_train", g.rmse_train}, {"rmse_val", g.rmse_val}, {"probe", false}});
    if (!g.removed.empty()) l.back()["removed"] = g.removed;
    if (!g.replaced_by.empty()) l.back()["replaced_by"] = g.replaced_by;
    if (g.refined) l.back()["refined"] = true;
    l.back()["model"] = io::modelToJson(g.model);  // each rung's fitted model: to try in closed loop
  }
  if (r.probe_rung) {
    const auto e = r.probes.front().effectsWith(r.ladder.back().effects);
    l.push_back({{"effects", e},
                 {"rmse_train", r.probes.front().rmse_train},
                 {"rmse_val", r.probes.front().rmse_val},
                 {"probe", true}});
  }
  j["ladder"] = l;
  nlohmann::json pj = nlohmann::json::array();
  for (const auto& p : r.probes) {
    nlohmann::json params = nlohmann::json::object();  // the probe's fitted parameters: a first guess at the physics
    for (int i = 0; i < p.model.numEffects(); ++i)
      if (p.probe == p.model.effect(i).name() || p.probe + model::kDirectionalSuffix == p.model.effect(i).name())
        for (size_t q = 0; q < p.model.effect(i).params().size(); ++q)
          params[p.model.effect(i).params()[q].name] = p.model.effectParams(i)[q];
    pj.push_back({{"probe", p.probe},
                  {"rmse_val", p.rmse_val},
                  {"rmse_train", p.rmse_train},
                  {"explains", p.explains},
                  {"regime", p.regime},
                  {"meaning", p.meaning},
                  {"params", params}});
    if (!p.replaces.empty()) pj.back()["replaces"] = p.replaces;
    if (!p.direction.empty()) pj.back()["direction"] = p.direction;
    if (p.symmetric_rmse_val > 0) pj.back()["symmetric_rmse_val"] = p.symmetric_rmse_val;
  }
  j["probes"] = pj;
  if (!r.probes_unresolved.empty()) j["probes_unresolved"] = r.probes_unresolved;
  j["spectrum"] = toJson(r.spectrum);
  j["model"] = io::modelToJson(r.ladder.back().model);
  j["verdict"] = r.verdict;
  j["seconds"] = r.seconds;
  return j;
}

void writeReport(const DiagnoseResult& r, const io::Measurement& data, const io::Measurement* val,
                 const DiagnoseSettings& /*s*/, const std::string& dir, std::vector<std::string>* warnings) {
  io::makeDirectory(dir, "report directory");
  const std::string p = dir + "/";
  // Ladder.
  {
    std::vector<double> rung, tr, va;
    std::string labels;
    for (size_t i = 0; i < r.ladder.size(); ++i) {
      rung.push_back(static_cast<double>(i));
      tr.push_back(r.ladder[i].rmse_train);
      va.push_back(r.ladder[i].rmse_val);
    }
    io::writeCsvAtomic(p + "ladder.csv", {"rung", "rmse_train", "rmse_val"}, {&rung, &tr, &va});
  }
  // Measured vs baseline vs final on the validation data.
  const io::Measurement& vd = val ? *val : data;
  const auto yb = simulate(r.ladder.front().model, vd);
  const auto yf = simulate(r.ladder.back().model, vd);
  std::vector<double> eb(vd.size()), ef(vd.size());
  for (size_t i = 0; i < vd.size(); ++i) eb[i] = vd.y[i] - yb[i], ef[i] = vd.y[i] - yf[i];
  io::writeCsvAtomic(p + "validation.csv", {"t", "u", "y", "y_reference", "y_final", "e_reference", "e_final"},
                     {&vd.t, &vd.u, &vd.y, &yb, &yf, &eb, &ef});
  // Residual tests of the baseline and the final model (training data).
  for (const auto& [name, rep] : {std::pair<std::string, const ResidualReport*>{"reference", &r.baseline_residual},
                                  {"final", &r.final_residual}}) {
    std::vector<double> lag, acf, up, dn;
    for (size_t i = 0; i < rep->acf.size(); ++i) {
      lag.push_back(static_cast<double>(i) * rep->lag_step_s);
      acf.push_back(rep->acf[i]);
      up.push_back(rep->conf);
      dn.push_back(-rep->conf);
    }
    std::vector<double> clag, ccf;
    for (size_t i = 0; i < rep->ccf_du.size(); ++i) {
      clag.push_back((static_cast<double>(i) - rep->max_lag) * rep->lag_step_s);
      ccf.push_back(rep->ccf_du[i]);
    }
    std::vector<double> cup(clag.size(), rep->conf), cdn(clag.size(), -rep->conf);
    io::writeCsvAtomic(p + "acf_" + name + ".csv", {"lag_s", "acf", "upper", "lower"}, {&lag, &acf, &up, &dn});
    io::writeCsvAtomic(p + "ccf_" + name + ".csv", {"lag_s", "ccf", "upper", "lower"}, {&clag, &ccf, &cup, &cdn});
  }
  // A folder used before keeps no probe table or chart that this diagnosis did not make.
  if (r.probes.empty())
    for (const char* f : {"probes.csv", "probes.png"}) std::remove((p + f).c_str());
  if (!r.probes.empty()) {
    // Probes: how much of what the final model leaves each explains (percent of the validated MSE).
    std::string t = "probe,explains_pct,rmse_val,regime\n";
    for (const auto& q : r.probes) {
      std::string regime = q.regime;
      std::replace(regime.begin(), regime.end(), ',', ';');
      t += q.label() + "," + fmt("%.2f", 100 * q.explains) + "," + fmt("%.6g", q.rmse_val) + "," + regime + "\n";
    }
    io::writeFileAtomic(p + "probes.csv", t);
  }
  auto ladder = toJson(r)["ladder"];
  for (auto& rung : ladder) rung.erase("model");  // the rungs' models are in diagnosis.json
  io::writeModelFile(p + "model.json", r.ladder.back().model, {{"ladder", ladder}});
  // The best probe, when it explains enough to be a rung, as a ready model: to check in closed loop
  // (pamc rig run --model, pamc experiments --model) whether the structure it points to matters there.
  if (r.probe_rung)
    io::writeModelFile(p + "probe_model.json", r.probes.front().model,
                       {{"probe", r.probes.front().label()},
                        {"note", r.probes.front().replaces.empty()
                                     ? "the final model with a probe on top: a kind of structure, not a physical model"
                                     : "the final model with a probe in place of " + r.probes.front().replaces +
                                           ": a kind of structure, not a physical model"},
                        {"rmse_val", r.probes.front().rmse_val}});
  else
    std::remove((p + "probe_model.json").c_str());
  io::writeFileAtomic(p + "diagnosis.json", toJson(r).dump(2) + "\n");
  writeSpectrumReport(r.spectrum, p, "The final model's residual in frequency (training data)", warnings);
  if (!report::haveGnuplot()) {
    if (warnings) warnings->push_back("gnuplot not found (apt-get install gnuplot-nox); figures skipped");
    return;
  }
  std::string err;
  const std::string vcsv = p + "validation.csv";
  auto fig = [&](const std::string& png, const std::string& title, const std::vector<report::Panel>& panels) {
    if (!report::renderFigure(p + png, title, panels, err) && warnings) warnings->push_back(err);
  };
  fig("ladder.png", "Error ladder: " + r.verdict.substr(0, 90),
      {{"RMSE after each added effect (0 = reference model)",
        "rung",
        "RMSE",
        {{p + "ladder.csv", "rung", "rmse_train", "training", "linespoints lw 2 pt 7"},
         {p + "ladder.csv", "rung", "rmse_val", "validation", "linespoints lw 2 pt 5"}}}});
  if (!r.probes.empty() &&
      !report::renderBars(
          p + "probes.png",
          "Probes: share of what " + join(r.ladder.back().effects) + " leaves that each explains (validation)",
          p + "probes.csv", 1, 2, "explained [%]", err) &&
      warnings)
    warnings->push_back(err);
  fig("validation.png",
      "Validation data: measured, reference model and final model (" + join(r.ladder.back().effects) + ")",
      {{"measured and models over time",
        "t [s]",
        "y",
        {{vcsv, "t", "y", "measured"},
         {vcsv, "t", "y_reference", "reference model"},
         {vcsv, "t", "y_final", "final model"}}},
       {"loops: y against u",
        "u",
        "y",
        {{vcsv, "u", "y", "measured"},
         {vcsv, "u", "y_reference", "reference model"},
         {vcsv, "u", "y_final", "final model"}}},
       {"residual over time",
        "t [s]",
        "y - model",
        {{vcsv, "t", "e_reference", "reference model"}, {vcsv, "t", "e_final", "final model"}}}});
  fig("residual_tests.png", "Residual tests (training data) with 95 % bounds",
      {{"auto-correlation of the residual",
        "lag [s]",
        "acf",
        {{p + "acf_reference.csv", "lag_s", "acf", "reference model"},
         {p + "acf_final.csv", "lag_s", "acf", "final model"},
         {p + "acf_reference.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
         {p + "acf_reference.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}},
       {"cross-correlation of the residual with the input increments",
        "lag [s]",
        "ccf",
        {{p + "ccf_reference.csv", "lag_s", "ccf", "reference model"},
         {p + "ccf_final.csv", "lag_s", "ccf", "final model"},
         {p + "ccf_reference.csv", "lag_s", "upper", "95 % bound", "lines dt 2 lc 'black'"},
         {p + "ccf_reference.csv", "lag_s", "lower", "", "lines dt 2 lc 'black'"}}}});
}

}  // namespace pamc::diagnose
