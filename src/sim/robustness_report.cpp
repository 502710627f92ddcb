#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>

#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "io/text.hpp"
#include "report/figures.hpp"
#include "sim/robustness_cells.hpp"

// The files of `pamc robustness` from cells documents: axis_*.csv, grid.csv, the heat maps, summary.txt
// and summary.json, the models identified with their records, and cells.json with every cell.
namespace pamc::sim {
namespace {

using detail::Cells;
using detail::meanAmcOverPi;
using io::fmt;

// ---------------------------------------------------------------- files

std::string scoreCells(const RobustnessScore& sc) {
  return sc.trajectory + "," + fmt("%.6g", sc.pi) + "," + fmt("%.6g", sc.eso) + "," + fmt("%.6g", sc.amc) + "," +
         fmt("%.6g", sc.amcOverPi()) + "," + fmt("%.6g", sc.esoOverPi()) + "," + fmt("%.6g", sc.mbc) + "," +
         fmt("%.6g", sc.mbcOverPi());
}

void writeAxisCsv(const std::string& dir, const AxisResult& r) {
  std::string out = "value,trajectory,pi_rmse,eso_rmse,amc_rmse,amc_over_pi,eso_over_pi,mbc_rmse,mbc_over_pi\n";
  for (size_t i = 0; i < r.axis.values.size(); ++i)
    for (const auto& sc : r.scores[i]) out += fmt("%.9g", r.axis.values[i]) + "," + scoreCells(sc) + "\n";
  io::writeFileAtomic(dir + "axis_" + r.axis.name + ".csv", out);
}

void writeGridCsv(const std::string& dir, const GridResult& g) {
  std::string out = g.row_axis + "," + g.col_axis +
                    ",trajectory,pi_rmse,eso_rmse,amc_rmse,amc_over_pi,eso_over_pi,mbc_rmse,mbc_over_pi\n";
  for (size_t r = 0; r < g.row_values.size(); ++r)
    for (size_t c = 0; c < g.col_values.size(); ++c)
      for (const auto& sc : g.scores[r][c])
        out += fmt("%.9g", g.row_values[r]) + "," + fmt("%.9g", g.col_values[c]) + "," + scoreCells(sc) + "\n";
  io::writeFileAtomic(dir + "grid.csv", out);
}

// ---------------------------------------------------------------- figures

using Ratio = double (RobustnessScore::*)() const;

std::vector<std::string> valueLabels(const RobustnessAxis& a) {
  std::vector<std::string> l;
  for (double v : a.values) l.push_back(fmt("%g", v) + (v == a.nominal ? " (nominal)" : ""));
  return l;
}

// Rows = the axis's values, columns = the trajectories.
report::Heatmap axisMap(const AxisResult& r, Ratio ratio, const std::string& what) {
  report::Heatmap m;
  m.title = what;
  m.xlabel = "trajectory";
  m.ylabel = r.axis.name + " [" + r.axis.unit + "]";
  m.yticks = valueLabels(r.axis);
  for (const auto& sc : r.scores.front()) m.xticks.push_back(sc.trajectory);
  for (const auto& row : r.scores) {
    m.z.emplace_back();
    for (const auto& sc : row) m.z.back().push_back((sc.*ratio)());
  }
  return m;
}

// One trajectory of the grid (index t), or the mean over the trajectories (t = npos).
report::Heatmap gridMap(const GridResult& g, const RobustnessAxis& rows, const RobustnessAxis& cols, Ratio ratio,
                        size_t t) {
  report::Heatmap m;
  m.title = t == std::string::npos ? "mean over the trajectories" : g.scores[0][0][t].trajectory;
  m.xlabel = cols.name + " [" + cols.unit + "]";
  m.ylabel = rows.name + " [" + rows.unit + "]";
  m.xticks = valueLabels(cols);
  m.yticks = valueLabels(rows);
  for (const auto& row : g.scores) {
    m.z.emplace_back();
    for (const auto& cell : row) {
      double sum = 0.0;
      for (const auto& sc : cell) sum += (sc.*ratio)();
      m.z.back().push_back(t == std::string::npos ? sum / static_cast<double>(cell.size()) : (cell[t].*ratio)());
    }
  }
  return m;
}

const char* kColourKey = "RMSE ratio (blue < 1: beats PI, red > 1: worse than PI)";

void renderAxis(const std::string& dir, const AxisResult& r, std::string& error) {
  const std::vector<report::Heatmap> maps = {axisMap(r, &RobustnessScore::amcOverPi, "PI+AMC / PI"),
                                             axisMap(r, &RobustnessScore::esoOverPi, "PID+ESO / PI")};
  const std::string title = "RMSE against PI over " + r.axis.label + " (nominal " + fmt("%g", r.axis.nominal) + " " +
                            r.axis.unit + ")" +
                            (r.axis.changesModel() ? "; the plant is nominal" : "; the model is nominal");
  if (!report::renderHeatmaps(dir + "axis_" + r.axis.name + ".png", title, maps, 1.0, kColourKey, error))
    throw std::runtime_error(error);
}

void renderGrid(const std::string& dir, const GridResult& g, const RobustnessAxis& rows, const RobustnessAxis& cols,
                Ratio ratio, const std::string& name, const std::string& what) {
  std::vector<report::Heatmap> maps;
  for (size_t t = 0; t < g.scores[0][0].size(); ++t) maps.push_back(gridMap(g, rows, cols, ratio, t));
  maps.push_back(gridMap(g, rows, cols, ratio, std::string::npos));
  std::string error;
  if (!report::renderHeatmaps(dir + name + ".png", what + " RMSE ratio over " + rows.name + " x " + cols.name, maps,
                              1.0, kColourKey, error, 3))
    throw std::runtime_error(error);
}

// ---------------------------------------------------------------- summary

nlohmann::json scoresJson(const std::vector<RobustnessScore>& scores) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& sc : scores)
    j[sc.trajectory] = {{"pi_rmse", sc.pi},
                        {"eso_rmse", sc.eso},
                        {"amc_rmse", sc.amc},
                        {"amc_over_pi", sc.amcOverPi()},
                        {"eso_over_pi", sc.esoOverPi()},
                        {"mbc_rmse", sc.mbc},
                        {"mbc_over_pi", sc.mbcOverPi()},
                        {"scored_from_s", sc.scored_from_s}};  // null: each run from its own first reach
  return j;
}

nlohmann::json axisJson(const AxisResult& r) {
  nlohmann::json rows = nlohmann::json::array();
  for (size_t i = 0; i < r.axis.values.size(); ++i)
    rows.push_back({{"value", r.axis.values[i]},
                    {"mean_amc_over_pi", r.mean_amc_over_pi[i]},
                    {"trajectories", scoresJson(r.scores[i])}});
  return {{"label", r.axis.label},
          {"unit", r.axis.unit},
          {"field", r.axis.field},
          {"nominal", r.axis.nominal},
          {"values", r.axis.values},
          {"spread_of_mean_amc_over_pi", r.spread},
          {"rows", rows}};
}

nlohmann::json gridJson(const GridResult& g) {
  nlohmann::json cells = nlohmann::json::array();
  for (size_t r = 0; r < g.row_values.size(); ++r)
    for (size_t c = 0; c < g.col_values.size(); ++c)
      cells.push_back(
          {{g.row_axis, g.row_values[r]}, {g.col_axis, g.col_values[c]}, {"trajectories", scoresJson(g.scores[r][c])}});
  return {{"rows", g.row_axis},
          {"columns", g.col_axis},
          {"row_values", g.row_values},
          {"column_values", g.col_values},
          {"cells", cells}};
}

// "triangle_0.05Hz" -> "tri.05Hz", "sine_0.1Hz" -> "sin.1Hz": a column head of the text tables.
std::string shortTag(std::string tag) {
  for (const char* long_form : {"triangle_0", "sine_0"}) {
    const std::string lf = long_form;
    if (tag.compare(0, lf.size(), lf) == 0) tag = lf.substr(0, 3) + tag.substr(lf.size());
  }
  return tag;
}

std::string ratioRow(const std::vector<RobustnessScore>& scores) {
  std::string amc, eso;
  for (const auto& sc : scores) {
    amc += fmt("%9.3f", sc.amcOverPi());
    eso += fmt("%9.3f", sc.esoOverPi());
  }
  return amc + " |" + eso;
}

std::string axisText(const AxisResult& r) {
  std::ostringstream t;
  t << "Axis " << r.axis.name << ": " << r.axis.label << " [" << r.axis.unit << "], nominal "
    << fmt("%g", r.axis.nominal) << "; spread of the mean AMC/PI " << fmt("%.3f", r.spread) << "\n";
  std::string head;
  for (const auto& sc : r.scores.front()) {
    char b[16];
    std::snprintf(b, sizeof b, "%9s", shortTag(sc.trajectory).c_str());
    head += b;
  }
  t << "  AMC/PI, ESO/PI and PI's RMSE [mm] by trajectory\n  value        " << head << " |" << head << " |" << head
    << "\n";
  for (size_t i = 0; i < r.axis.values.size(); ++i) {
    std::string pi;
    for (const auto& sc : r.scores[i]) pi += fmt("%9.3f", sc.pi);
    t << "  " << fmt("%-10g", r.axis.values[i]) << (r.axis.values[i] == r.axis.nominal ? "*" : " ") << "  "
      << ratioRow(r.scores[i]) << " |" << pi << "\n";
  }
  return t.str() + "\n";
}

std::string gridText(const GridResult& g) {
  std::ostringstream t;
  t << "Grid " << g.row_axis << " (rows) x " << g.col_axis
    << " (columns): AMC/PI RMSE ratio, mean over the trajectories\n";
  t << std::string(12, ' ');
  for (double c : g.col_values) t << fmt("%10g", c);
  t << "\n";
  for (size_t r = 0; r < g.row_values.size(); ++r) {
    t << "  " << fmt("%10g", g.row_values[r]);
    for (const auto& cell : g.scores[r]) t << fmt("%10.3f", meanAmcOverPi(cell));
    t << "\n";
  }
  return t.str() + "\n";
}

// ---------------------------------------------------------------- the merge's steps

void renderFigures(const std::string& dir, const RobustnessReport& rep, const std::vector<RobustnessAxis>& axes,
                   const RobustnessSettings& s) {
  if (!s.figures) return;
  if (!report::haveGnuplot()) {
    if (s.log) s.log("warning: gnuplot not found (apt-get install gnuplot-nox); heat maps skipped, CSVs written");
    return;
  }
  try {
    std::string error;
    for (const auto& r : rep.axes) renderAxis(dir, r, error);
    if (rep.grid.scores.empty()) return;
    const RobustnessAxis rows = selectAxes(axes, {rep.grid.row_axis}).front();
    const RobustnessAxis cols = selectAxes(axes, {rep.grid.col_axis}).front();
    renderGrid(dir, rep.grid, rows, cols, &RobustnessScore::amcOverPi, "grid_amc_over_pi", "PI+AMC / PI");
    renderGrid(dir, rep.grid, rows, cols, &RobustnessScore::esoOverPi, "grid_eso_over_pi", "PID+ESO / PI");
  } catch (const std::runtime_error& e) {
    if (s.log) s.log(std::string("warning: ") + e.what());
  }
}

void writeSummary(const std::string& dir, RobustnessReport& rep, const RobustnessSettings& s) {
  std::ostringstream t;
  t << "RMSE of PID+ESO and PI+AMC against PI (ratio < 1: better than PI) on the triangle, the two sines and the\n"
       "square wave, over plant changes the controllers were not tuned for ('*': nominal).\n"
    << (s.common_window
            ? "The sines (started away from home) are scored over one window for all four controllers, from the\n"
              "latest of their first reaches.\n\n"
            : "Every run is scored from its own first reach (Table 2's rule).\n\n");
  nlohmann::json axes = nlohmann::json::object();
  for (const auto& r : rep.axes) {
    t << axisText(r);
    axes[r.axis.name] = axisJson(r);
  }
  t << "Strongest axes (largest spread of the mean AMC/PI ratio):";
  for (const auto& n : rep.strongest) t << " " << n;
  t << "\n\n";
  if (!rep.grid.scores.empty()) t << gridText(rep.grid);
  t << rep.variants << " variants x " << rep.axes.front().scores.front().size()
    << " trajectories x 4 controllers: " << fmt("%.1f", rep.seconds) << " s of runs in " << rep.shards
    << (rep.shards == 1 ? " part" : " parts") << " on " << s.threads << " worker threads each\n";
  if (rep.pairs_pending) t << "The pairs grid is not run yet (pamc robustness --pairs-of DIR --shard I/N).\n";
  rep.text = t.str();
  rep.json = {{"axes", axes},
              {"strongest", rep.strongest},
              {"variants", rep.variants},
              {"seconds", rep.seconds},
              {"threads", s.threads},
              {"shards", rep.shards},
              {"pairs_pending", rep.pairs_pending},
              {"score_from", s.common_window ? "common" : "own"},
              {"plant", s.plant.toJson()}};
  if (!rep.grid.scores.empty()) rep.json["grid"] = gridJson(rep.grid);
  io::writeFileAtomic(dir + "summary.txt", rep.text);
  io::writeFileAtomic(dir + "summary.json", rep.json.dump(2) + "\n");
}

// ---------------------------------------------------------------- checking and combining the parts

std::string sourceOf(const nlohmann::json& d) { return d.value("source", std::string("a cells document")); }

std::string partText(const nlohmann::json& d) {
  return std::to_string(d.at("shard").at("index").get<int>()) + "/" +
         std::to_string(d.at("shard").at("count").get<int>());
}

// The first top-level setting in which two documents differ.
std::string firstDifference(const nlohmann::json& a, const nlohmann::json& b) {
  for (const auto& [key, value] : a.items())
    if (!b.contains(key) || b.at(key) != value) return key;
  return "a setting";
}

void checkOne(const nlohmann::json& d, const nlohmann::json& first) {
  if (!d.is_object() || d.value("format", "") != detail::kCellsFormat)
    throw std::invalid_argument(sourceOf(d) + ": not a cells document (" + detail::kCellsFormat + ")");
  if (d.at("settings") != first.at("settings"))
    throw std::invalid_argument(sourceOf(d) + ": run with other settings than " + sourceOf(first) + " (its '" +
                                firstDifference(d.at("settings"), first.at("settings")) + "' differs)");
  if (d.at("phase") != first.at("phase"))
    throw std::invalid_argument(sourceOf(d) + ": a part of the " + d.at("phase").get<std::string>() + ", " +
                                sourceOf(first) + " of the " + first.at("phase").get<std::string>() +
                                " (merge the parts of one phase)");
  if (d.at("shard").at("count") != first.at("shard").at("count"))
    throw std::invalid_argument(sourceOf(d) + ": part " + partText(d) + ", " + sourceOf(first) + " part " +
                                partText(first) + " (one N for all parts)");
}

// Documents of one phase with the same settings and N, every part once.
void checkParts(const std::vector<nlohmann::json>& docs) {
  if (docs.empty()) throw std::invalid_argument("nothing to merge");
  std::map<int, std::string> seen;
  for (const auto& d : docs) {
    checkOne(d, docs.front());
    const int i = d.at("shard").at("index").get<int>();
    if (seen.count(i))
      throw std::invalid_argument("part " + partText(d) + " given twice: " + seen[i] + " and " + sourceOf(d));
    seen[i] = sourceOf(d);
  }
  const int n = docs.front().at("shard").at("count").get<int>();
  for (int i = 1; i <= n; ++i)
    if (!seen.count(i))
      throw std::invalid_argument("part " + std::to_string(i) + "/" + std::to_string(n) + " of the " +
                                  docs.front().at("phase").get<std::string>() + " is missing");
}

// One document with every part's cells and models; its seconds the parts' added.
nlohmann::json combine(const std::vector<nlohmann::json>& docs) {
  nlohmann::json merged = docs.front();
  merged.erase("source");
  double seconds = 0.0;
  for (const auto& d : docs) {
    for (const auto& [key, cell] : d.at("cells").items()) merged["cells"][key] = cell;
    for (const auto& [tag, m] : d.at("models").items()) merged["models"][tag] = m;
    if (d.contains("nominal_model")) merged["nominal_model"] = d.at("nominal_model");
    seconds += d.value("seconds", 0.0);
  }
  const int n = docs.front().at("shard").at("count").get<int>();
  merged["parts"] = std::max(n, docs.front().value("parts", 1));
  merged["shard"] = {{"index", 1}, {"count", 1}};
  merged["seconds"] = seconds;
  return merged;
}

// The models identified, with the records they were identified on (recorded again: the same bytes).
void writeModels(const std::string& dir, const RobustnessSettings& s, const nlohmann::json& models) {
  for (const auto& [tag, m] : models.items()) {
    recordOpenLoop(s.plant, identInput(m.at("amplitude").get<double>()), kIdentDuration,
                   dir + "ident_A" + tag + ".csv");
    io::writeModelFile(dir + "model_A" + tag + ".json", io::modelFromJson(m.at("model"), "cells: model " + tag),
                       m.at("fit"));
  }
}

// The results of the merged cells: the axes, the two strongest, the grid when its cells are there.
RobustnessReport resultsOf(const nlohmann::json& merged, const RobustnessSettings& s) {
  const Cells cells = detail::cellsFromJson(merged.at("cells"), "cells");
  if (!detail::allIn(detail::axisVariants(s.axes), cells))
    throw std::invalid_argument("the axes' cells are not all there");
  RobustnessReport rep;
  rep.axes = detail::axisResults(cells, s.axes);
  const auto strong = detail::strongestTwo(rep.axes);
  for (const auto* a : strong) rep.strongest.push_back(a->axis.name);
  if (s.grid && strong.size() == 2) {
    const RobustnessAxis& rows = strong[0]->axis;
    const RobustnessAxis& cols = strong[1]->axis;
    if (detail::allIn(detail::gridVariants(rows, cols), cells))
      rep.grid = detail::gridResult(cells, rows, cols);
    else
      rep.pairs_pending = true;
  }
  rep.variants = static_cast<int>(cells.size());
  rep.seconds = merged.value("inherited_seconds", 0.0) + merged.value("seconds", 0.0);
  rep.shards = merged.value("parts", 1);
  return rep;
}

}  // namespace

nlohmann::json readRobustnessCells(const std::string& dir) {
  nlohmann::json d = io::readJsonFile(dir + "/cells.json", "cells document (pamc robustness writes it)");
  if (!d.is_object()) throw io::InputError(dir + "/cells.json: not a cells document");
  d["source"] = dir;
  return d;
}

RobustnessReport mergeRobustness(const std::vector<nlohmann::json>& docs, const RobustnessSettings& out) {
  checkParts(docs);
  const nlohmann::json merged = combine(docs);
  RobustnessSettings s = robustnessSettingsFromJson(merged.at("settings"));
  s.out_dir = out.out_dir, s.figures = out.figures, s.log = out.log;
  s.threads = merged.value("threads", out.threads);
  RobustnessReport rep = resultsOf(merged, s);
  io::makeDirectory(s.out_dir);
  const std::string dir = s.out_dir + "/";
  writeModels(dir, s, merged.at("models"));
  for (const auto& r : rep.axes) writeAxisCsv(dir, r);
  if (!rep.grid.scores.empty()) writeGridCsv(dir, rep.grid);
  renderFigures(dir, rep, s.axes, s);
  writeSummary(dir, rep, s);
  io::writeFileAtomic(dir + "cells.json", merged.dump(1) + "\n");
  return rep;
}

}  // namespace pamc::sim
