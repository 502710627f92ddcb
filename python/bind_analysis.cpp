// The modelling tools: fit, compare, diagnose, and the paper's experiments. Each returns what its
// command writes as JSON (built by the same library function) and releases the GIL while it runs.
#include <cstdio>

#include <pybind11/stl.h>

#include "bind.hpp"
#include "convert.hpp"
#include "diagnose/compare.hpp"
#include "diagnose/diagnose.hpp"
#include "ident/identify.hpp"
#include "io/model_file.hpp"
#include "sim/experiments.hpp"

namespace pamc::python {
namespace {

ident::FitMethod methodOf(const std::string& name, const model::Model& structure) {
  return name == "auto" ? ident::autoFitMethod(structure) : ident::fitMethodFromString(name);
}

py::tuple fit(const io::Measurement& d, const std::vector<std::string>& effects, const std::string& method,
              std::uint64_t seed, int threads, const std::string& output_form,
              const std::optional<model::Model>& start) {
  model::Model structure;
  model::OutputForm form;
  if (!model::parseOutputForm(output_form, form))
    throw std::invalid_argument("output_form: '" + output_form + "' (aligned, printed)");
  structure.setOutputForm(form);
  for (const auto& e : effects) structure.addEffect(e);
  ident::FitSettings fs = ident::FitSettings::forMethod(methodOf(method, structure));
  fs.ga.seed = seed;
  fs.ga.threads = threads;
  fs.box_holds_start = true;
  ident::FitResult r;
  {
    py::gil_scoped_release free;
    r = ident::fit(structure, d, fs, {}, start ? &*start : nullptr);
  }
  return py::make_tuple(r.model, toPython(ident::fitReport(r, fs, d, d.source)));
}

py::dict compare(const model::Model& m, const io::Measurement& d) {
  diagnose::Comparison c;
  {
    py::gil_scoped_release free;
    c = diagnose::compare(m, d);
  }
  std::vector<double> e(d.size());
  for (size_t i = 0; i < d.size(); ++i) e[i] = d.y[i] - c.y_model[i];
  py::dict out = toPython(diagnose::toJson(c));
  out["t"] = toArray(std::vector<double>(d.t));
  out["y_model"] = toArray(std::move(c.y_model));
  out["residual"] = toArray(std::move(e));
  return out;
}

py::dict diagnoseData(const io::Measurement& d, const std::optional<io::Measurement>& val, const py::dict& kw) {
  diagnose::DiagnoseSettings s;
  for (const auto& [k, v] : kw) {
    const std::string name = py::str(k);
    if (name == "holdout")
      s.holdout = v.cast<double>();
    else if (name == "max_effects")
      s.max_effects = v.cast<int>();
    else if (name == "min_gain")
      s.min_gain = v.cast<double>();
    else if (name == "candidates")
      s.candidates = v.cast<std::vector<std::string>>();
    else if (name == "seed")
      s.seed = v.cast<std::uint64_t>();
    else if (name == "threads")
      s.threads = v.cast<int>();
    else if (name == "method")
      s.method = ident::fitMethodFromString(v.cast<std::string>());
    else if (name == "probes")
      s.probes = v.cast<bool>();
    else if (name == "output_form" && !model::parseOutputForm(v.cast<std::string>(), s.output_form))
      throw std::invalid_argument("output_form: '" + v.cast<std::string>() + "' (aligned, printed)");
    else if (name != "output_form")
      throw py::type_error("diagnose: unknown setting '" + name + "'");
  }
  diagnose::DiagnoseResult r;
  {
    py::gil_scoped_release free;
    r = diagnose::diagnose(d, val ? &*val : nullptr, s);
  }
  py::dict out = toPython(diagnose::toJson(r));
  out["final_model"] = r.ladder.back().model;  // "model" holds it as the JSON does
  return out;
}

py::dict experiments(const std::string& out_dir, const std::vector<std::string>& only, std::uint64_t seed, bool figures,
                     const py::object& plant, const py::object& model, const std::string& sine_start, bool verbose,
                     const py::kwargs& gains) {
  sim::ExperimentSettings s;
  if (!plant.is_none()) {
    s.plant = plantConfigOf(plant);
    s.calibrated_on = "not calibrated: the plant given";
  }
  s.out_dir = out_dir;
  if (!model.is_none()) s.model_file = pathOf(model);
  s.figures = figures;
  if (sine_start != "centre" && sine_start != "trough")
    throw std::invalid_argument("sine_start: '" + sine_start + "' (centre, trough)");
  s.sine_start = sine_start == "trough" ? sim::SineStart::Trough : sim::SineStart::Centre;
  s.only = only;
  s.fit.ga.seed = seed;
  applyControllerSettings(s.ctrl, gains);
  if (verbose) s.log = [](const std::string& line) { std::fprintf(stderr, "%s\n", line.c_str()); };
  sim::ExperimentReport rep;
  {
    py::gil_scoped_release free;
    rep = s.model_file.empty() ? sim::runExperiments(s)
                               : readingFile(s.model_file, [&] { return sim::runExperiments(s); });
  }
  return toPython(rep.json);
}

}  // namespace

void bindAnalysis(py::module_& m) {
  m.def("_fit", &fit, py::arg("data"), py::arg("effects"), py::arg("method"), py::arg("seed"), py::arg("threads"),
        py::arg("output_form"), py::arg("start"));
  m.def("_compare", &compare, py::arg("model"), py::arg("data"));
  m.def(
      "_diagnose",
      [](const io::Measurement& d, const std::optional<io::Measurement>& val, const py::kwargs& kw) {
        return diagnoseData(d, val, kw);
      },
      py::arg("data"), py::arg("validate") = py::none());
  m.def("experiments", &experiments, py::arg("out_dir") = "results", py::arg("only") = std::vector<std::string>{},
        py::arg("seed") = 1, py::arg("figures") = false, py::arg("plant") = py::none(), py::arg("model") = py::none(),
        py::arg("sine_start") = "centre", py::arg("verbose") = false);
}

}  // namespace pamc::python
