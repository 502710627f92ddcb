#include "sim/calibration.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include <sys/stat.h>

#include "io/text.hpp"

namespace pamc::sim {

namespace {

using io::fmt;

// The summaries' numbers by path (paper_criteria.hpp).
double at(const nlohmann::json& j, std::initializer_list<const char*> path) { return jsonNumber(j, path); }

double distanceToPaper(const nlohmann::json& s) {
  double sum = 0;
  int n = 0;
  const char* u[3] = {"u0", "u1", "u2"};
  for (int i = 0; i < 3; ++i) {
    sum += std::fabs(std::log(at(s, {"table1", u[i], "reference_rmse"}) / PaperNumbers::table1_reference[i]));
    ++n;
  }
  const char* cols[3] = {"pi", "eso", "amc"};
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) {
      sum += std::fabs(std::log(at(s, {"table2", PaperNumbers::table2_rows[r], cols[c], "rmse"}) /
                                PaperNumbers::table2[r][c + 1][1]));
      ++n;
    }
  return std::isfinite(sum) ? sum / n : INFINITY;
}

}  // namespace

std::vector<CalibrationRow> runCalibration(const CalibrationSettings& s) {
  std::vector<CalibrationRow> rows;
  if (s.base.plant.kind != plant::PlantKind::Model)
    throw std::invalid_argument("calibrate varies the pressure lag of a model plant: give a plant file with \"kind\": \"model\"");
  ::mkdir(s.work_dir.c_str(), 0755);
  const std::vector<double> eso_tau = s.eso_tau.empty() ? std::vector<double>{s.base.ctrl.eso_tau} : s.eso_tau;
  const std::vector<double> eso_wo = s.eso_wo.empty() ? std::vector<double>{s.base.ctrl.eso_wo} : s.eso_wo;
  const size_t total = s.lag_tau_s.size() * s.ki.size() * s.amc_as_printed.size() * eso_tau.size() * eso_wo.size();
  size_t done = 0;
  for (double tau : s.lag_tau_s) {
    ExperimentSettings es = s.base;
    es.figures = false;
    es.log = nullptr;
    if (!es.plant.truth.hasEffect("pressure_lag")) es.plant.truth.addEffect("pressure_lag");
    es.plant.truth.setEffectParam("pressure_lag", "tau", tau);
    es.out_dir = s.work_dir + "/tau_" + fmt("%g", tau);
    std::string model_file;  // identified once per emulator, reused for every gain reading
    for (double ki : s.ki)
      for (bool printed : s.amc_as_printed)
        for (double e_tau : eso_tau)
          for (double e_wo : eso_wo) {
        es.ctrl.ki = ki;
        es.ctrl.amc_as_printed = printed;
        es.ctrl.eso_tau = e_tau;
        es.ctrl.eso_wo = e_wo;
        es.model_file = model_file;
        const auto rep = runExperiments(es);
        if (model_file.empty()) model_file = es.out_dir + "/model.json";
        CalibrationRow row;
        row.lag_tau_s = tau;
        row.ki = ki;
        row.amc_as_printed = printed;
        row.eso_tau = e_tau;
        row.eso_wo = e_wo;
        row.summary = rep.json;
        row.criteria = paperCriteria(rep.json);
        row.met = criteriaMet(row.criteria);
        row.distance = distanceToPaper(rep.json);
        rows.push_back(std::move(row));
        ++done;
        if (s.log)
          s.log("calibrate: " + std::to_string(done) + "/" + std::to_string(total) + "  tau " + fmt("%g", tau) +
                " s, ki " + fmt("%g", ki) + (printed ? ", eq. 17 as printed" : ", eq. 17 as increment") + ", ESO tau " +
                fmt("%g", e_tau) + " s wo " + fmt("%g", e_wo) + " rad/s: " +
                std::to_string(rows.back().met) + "/" + std::to_string(rows.back().criteria.size()) +
                " criteria, distance " + fmt("%.3f", rows.back().distance));
      }
  }
  return rows;
}

void rankCalibration(std::vector<CalibrationRow>& rows) {
  std::stable_sort(rows.begin(), rows.end(), [](const CalibrationRow& a, const CalibrationRow& b) {
    if (a.met != b.met) return a.met > b.met;
    return a.distance < b.distance;
  });
}

std::string formatCalibration(const std::vector<CalibrationRow>& rows, int mark) {
  std::string t =
      "| lag tau [s] | ki [V/(mm s)] | eq. 17 | ESO tau [s] / wo [rad/s] | Table 1 u0 / u1 / u2 | triangle PI / ESO / AMC | sine 0.05 Hz PI / ESO / "
      "AMC | sine 0.1 Hz PI / ESO / AMC | triangle max PI / ESO / AMC | square fwd PI os / AMC os, settle | payload "
      "AMC best | criteria | distance |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  // The paper's own row.
  t += "| paper | | | | " + fmt("%.2f", PaperNumbers::table1_reference[0]) + " / " +
       fmt("%.2f", PaperNumbers::table1_reference[1]) + " / " + fmt("%.2f", PaperNumbers::table1_reference[2]) + " |";
  for (int r = 0; r < 3; ++r)
    t += " " + fmt("%.3f", PaperNumbers::table2[r][1][1]) + " / " + fmt("%.3f", PaperNumbers::table2[r][2][1]) + " / " +
         fmt("%.3f", PaperNumbers::table2[r][3][1]) + " |";
  t += " " + fmt("%.2f", PaperNumbers::table2[0][1][0]) + " / " + fmt("%.2f", PaperNumbers::table2[0][2][0]) + " / " +
       fmt("%.2f", PaperNumbers::table2[0][3][0]) + " | ~17 % / negligible, < 0.5 s | yes | | |\n";
  for (size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    const auto& s = r.summary;
    const std::string b = static_cast<int>(i) == mark ? "**" : "";
    t += "| " + b + fmt("%g", r.lag_tau_s) + b + " | " + b + fmt("%g", r.ki) + b + " | " +
         (r.amc_as_printed ? "printed" : "increment") + " | " + fmt("%g", r.eso_tau) + " / " + fmt("%g", r.eso_wo) +
         " | " + fmt("%.2f", at(s, {"table1", "u0", "reference_rmse"})) +
         " / " + fmt("%.2f", at(s, {"table1", "u1", "reference_rmse"})) + " / " +
         fmt("%.2f", at(s, {"table1", "u2", "reference_rmse"})) + " |";
    for (int row = 0; row < 3; ++row) {
      const char* tr = PaperNumbers::table2_rows[row];
      t += " " + fmt("%.3f", at(s, {"table2", tr, "pi", "rmse"})) + " / " + fmt("%.3f", at(s, {"table2", tr, "eso", "rmse"})) +
           " / " + fmt("%.3f", at(s, {"table2", tr, "amc", "rmse"})) + " |";
    }
    const char* tri = PaperNumbers::table2_rows[0];
    t += " " + fmt("%.2f", at(s, {"table2", tri, "pi", "max"})) + " / " + fmt("%.2f", at(s, {"table2", tri, "eso", "max"})) +
         " / " + fmt("%.2f", at(s, {"table2", tri, "amc", "max"})) + " |";
    t += " " + fmt("%.1f %%", at(s, {"discontinuous", "square", "forward", "pi", "overshoot_pct"})) + " / " +
         fmt("%.1f %%", at(s, {"discontinuous", "square", "forward", "amc", "overshoot_pct"})) + ", " +
         fmt("%.2f s", at(s, {"discontinuous", "square", "forward", "amc", "settling_s"})) + " |";
    bool pay = false;
    for (const auto& c : r.criteria)
      if (c.name == "payload_amc_best") pay = c.ok;
    t += std::string(" ") + (pay ? "yes" : "no") + " | " + std::to_string(r.met) + "/" +
         std::to_string(r.criteria.size()) + " | " + fmt("%.3f", r.distance) + " |\n";
  }
  return t;
}

}  // namespace pamc::sim
