// The robustness sweep's cells from Python (pamc.sweep, docs/PYTHON.md): the settings as a dict, a part
// of a phase's cells, the merge into the files one run writes. The same functions as `pamc robustness
// --shard/--pairs-of/--merge`; each releases the GIL while it runs.
#include <cstdio>

#include <pybind11/stl.h>

#include "bind.hpp"
#include "convert.hpp"
#include "ident/identify.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "sim/calibration.hpp"
#include "sim/robustness.hpp"

namespace pamc::python {
namespace {

void logToStderr(const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); }

py::dict settings(const py::object& plant, const py::object& model, const std::vector<std::string>& only_axes,
                  std::uint64_t seed, bool pairs, const std::string& score_from, double duration_scale,
                  const std::string& fit_method, const py::kwargs& gains) {
  sim::RobustnessSettings s;
  if (!plant.is_none()) s.plant = plantConfigOf(plant);
  if (!model.is_none()) {
    s.model_file = pathOf(model);
    readingFile(s.model_file, [&] { return io::readModelFile(s.model_file); });  // missing: FileNotFoundError now
  }
  s.only_axes = only_axes;
  s.fit = ident::FitSettings::forMethod(ident::fitMethodFromString(fit_method));
  s.fit.ga.seed = seed;
  s.grid = pairs;
  if (score_from != "common" && score_from != "own")
    throw std::invalid_argument("score_from: '" + score_from + "' (common, own)");
  s.common_window = score_from == "common";
  if (!(duration_scale > 0.0 && duration_scale <= 1.0)) throw std::invalid_argument("duration_scale: from 0 to 1");
  s.duration_scale = duration_scale;
  applyControllerSettings(s.ctrl, gains);
  return toPython(sim::robustnessSettingsJson(s));
}

py::dict cells(const py::dict& settings, int index, int count, const std::string& out_dir, int threads,
               const py::object& pairs_of, bool verbose) {
  sim::RobustnessSettings s = sim::robustnessSettingsFromJson(fromPython(settings));
  s.out_dir = out_dir, s.shard = {index, count}, s.threads = threads;
  if (verbose) s.log = logToStderr;
  const nlohmann::json axes = pairs_of.is_none() ? nlohmann::json() : fromPython(pairs_of);
  nlohmann::json doc;
  {
    py::gil_scoped_release free;
    doc = sim::runRobustnessCells(s, pairs_of.is_none() ? nullptr : &axes);
  }
  return toPython(doc);
}

py::tuple merge(const std::vector<py::dict>& parts, const std::string& out_dir, bool figures, bool verbose) {
  std::vector<nlohmann::json> docs;
  for (const auto& p : parts) docs.push_back(fromPython(p));
  sim::RobustnessSettings out;
  out.out_dir = out_dir, out.figures = figures;
  if (verbose) out.log = logToStderr;
  sim::RobustnessReport rep;
  {
    py::gil_scoped_release free;
    rep = sim::mergeRobustness(docs, out);
  }
  return py::make_tuple(toPython(rep.json), toPython(sim::readRobustnessCells(out_dir)));
}

sim::CalibrationSettings calibrationSettings(const std::vector<double>& ki_grid, const std::vector<std::string>& axes,
                                             const std::string& work_dir) {
  sim::CalibrationSettings s;
  if (!ki_grid.empty()) s.ki_grid = ki_grid;
  s.axes = axes;
  s.work_dir = work_dir;
  return s;
}

py::list pointsList(const std::vector<sim::CalibrationPoint>& points) {
  py::list out;
  for (const auto& p : points) out.append(toPython(sim::calibrationPointToJson(p)));
  return out;
}

// One candidate plant's points (a task on a worker): its runs in work_dir.
py::list calibrationPlant(const std::vector<double>& ki_grid, const std::vector<double>& values,
                          const std::string& work_dir) {
  const sim::CalibrationSettings s = calibrationSettings(ki_grid, {}, work_dir);
  std::vector<sim::CalibrationPoint> points;
  {
    py::gil_scoped_release free;
    io::makeDirectory(work_dir);
    points = sim::evaluateCalibrationPlant(s, values);
  }
  return pointsList(points);
}

// The batch through the Python callable `evaluate(batch) -> [[point, ...], ...]` (called with the GIL).
sim::CalibrationEvaluator pythonEvaluator(const py::object& evaluate) {
  return [evaluate](const std::vector<std::vector<double>>& batch) {
    py::gil_scoped_acquire hold;
    std::vector<std::vector<sim::CalibrationPoint>> out;
    for (const auto& plant : evaluate(py::cast(batch))) {
      out.emplace_back();
      for (const auto& p : plant) out.back().push_back(sim::calibrationPointFromJson(fromPython(p)));
    }
    return out;
  };
}

py::dict calibrate(const std::vector<double>& ki_grid, const std::vector<std::string>& axes, int passes, int threads,
                   const std::string& work_dir, const py::object& evaluate, bool verbose) {
  sim::CalibrationSettings s = calibrationSettings(ki_grid, axes, work_dir);
  s.passes = passes, s.threads = threads;
  if (!evaluate.is_none()) s.evaluate = pythonEvaluator(evaluate);
  if (verbose) s.log = logToStderr;
  sim::CalibrationResult r;
  {
    py::gil_scoped_release free;
    r = sim::runCalibration(s);
  }
  py::dict out;
  out["table"] = sim::formatCalibration(r);
  out["points"] = pointsList(r.tried);
  out["best"] = r.best;
  return out;
}

}  // namespace

void bindSweep(py::module_& m) {
  m.def("_calibration_plant", &calibrationPlant, py::arg("ki_grid"), py::arg("values"), py::arg("work_dir"));
  m.def("_calibrate", &calibrate, py::arg("ki_grid"), py::arg("axes"), py::arg("passes"), py::arg("threads"),
        py::arg("work_dir"), py::arg("evaluate") = py::none(), py::arg("verbose") = false);
  m.def("_robustness_settings", &settings, py::arg("plant") = py::none(), py::arg("model") = py::none(),
        py::arg("only_axes") = std::vector<std::string>{}, py::arg("seed") = 1, py::arg("pairs") = true,
        py::arg("score_from") = "common", py::arg("duration_scale") = 1.0, py::arg("fit_method") = "ga");
  m.def("_robustness_cells", &cells, py::arg("settings"), py::arg("index"), py::arg("count"), py::arg("out_dir"),
        py::arg("threads") = 1, py::arg("pairs_of") = py::none(), py::arg("verbose") = false);
  m.def("_robustness_merge", &merge, py::arg("parts"), py::arg("out_dir"), py::arg("figures") = true,
        py::arg("verbose") = false);
}

}  // namespace pamc::python
