// pamc.Model and the measurement files (pamc.Measurement, read_csv, write_csv).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>

#include <pybind11/stl.h>

#include "bind.hpp"
#include "convert.hpp"
#include "io/measurement.hpp"
#include "io/model_file.hpp"
#include "model/model.hpp"

namespace pamc::python {
namespace {

using model::Model;

// The arrays as the CSV text they would be in a file (17 digits: the same doubles when read back).
std::string csvText(const std::vector<std::string>& header, const std::vector<std::vector<double>>& cols) {
  std::string text;
  for (size_t c = 0; c < header.size(); ++c) text += (c ? "," : "") + header[c];
  text += '\n';
  char buf[32];
  for (size_t i = 0; i < cols[0].size(); ++i) {
    for (size_t c = 0; c < cols.size(); ++c) {
      std::snprintf(buf, sizeof buf, c ? ",%.17g" : "%.17g", cols[c][i]);
      text += buf;
    }
    text += '\n';
  }
  return text;
}

// A measurement of arrays, checked by the reader of measurement files (its limits and one-line errors,
// which name sample i as line i + 2 of `source`).
io::Measurement measurementOf(const Array& t, const Array& u, const Array& y, const py::dict& extra,
                              const std::string& source) {
  std::vector<std::string> header{"t", "u", "y"};
  std::vector<std::vector<double>> cols{toVector(t, "t"), toVector(u, "u"), toVector(y, "y")};
  for (const auto& [k, v] : extra) {
    if (v.is_none()) continue;
    header.push_back(py::str(k));
    cols.push_back(toVector(v.cast<Array>(), header.back().c_str()));
  }
  for (size_t c = 1; c < cols.size(); ++c)
    if (cols[c].size() != cols[0].size())
      throw io::InputError(source + ": " + header[c] + " has " + std::to_string(cols[c].size()) + " samples, t has " +
                           std::to_string(cols[0].size()));
  return io::parseMeasurementCsv(csvText(header, cols), source);
}

py::object column(const io::Measurement& m, const std::string& name, const py::handle& self) {
  const auto* c = m.column(name);
  return c ? py::object(viewOf(*c, self)) : py::object(py::none());
}

void bindMeasurement(py::module_& mod) {
  py::class_<io::Measurement>(mod, "Measurement")
      .def(py::init([](const Array& t, const Array& u, const Array& y, const std::string& source,
                       const py::kwargs& kw) { return measurementOf(t, u, y, kw, source); }),
           py::arg("t"), py::arg("u"), py::arg("y"), py::kw_only(), py::arg("source") = "arrays")
      .def_property_readonly("t", [](py::object s) { return viewOf(s.cast<const io::Measurement&>().t, s); })
      .def_property_readonly("u", [](py::object s) { return viewOf(s.cast<const io::Measurement&>().u, s); })
      .def_property_readonly("y", [](py::object s) { return viewOf(s.cast<const io::Measurement&>().y, s); })
      .def_property_readonly("load", [](py::object s) { return column(s.cast<const io::Measurement&>(), "load", s); })
      .def_property_readonly("p", [](py::object s) { return column(s.cast<const io::Measurement&>(), "p", s); })
      .def_property_readonly("columns",
                             [](py::object s) {
                               py::dict d;
                               for (const auto& [k, v] : s.cast<const io::Measurement&>().extra)
                                 d[py::str(k)] = viewOf(v, s);
                               return d;
                             })
      .def_readonly("Ts", &io::Measurement::Ts)
      .def_readonly("source", &io::Measurement::source)
      .def("__len__", &io::Measurement::size)
      .def("__repr__", [](const io::Measurement& m) {
        return "<pamc.Measurement " + m.source + ": " + std::to_string(m.size()) + " samples>";
      });

  mod.def(
      "read_csv",
      [](const py::object& p) {
        const std::string path = pathOf(p);
        std::vector<std::string> warnings;
        auto m = readingFile(path, [&] { return io::readMeasurementCsv(path, &warnings); });
        for (const auto& w : warnings) PyErr_WarnEx(PyExc_UserWarning, w.c_str(), 1);
        return m;
      },
      py::arg("path"));
  mod.def(
      "write_csv",
      [](const py::object& p, const Array& t, const Array& u, const Array& y, const py::kwargs& kw) {
        const auto m = measurementOf(t, u, y, kw, pathOf(p));
        std::vector<std::string> header{"t", "u", "y"};
        std::vector<const std::vector<double>*> cols{&m.t, &m.u, &m.y};
        for (const auto& [k, v] : m.extra) header.push_back(k), cols.push_back(&v);
        io::writeCsvAtomic(m.source, header, cols, 17);
      },
      py::arg("path"), py::arg("t"), py::arg("u"), py::arg("y"));
}

py::dict parameters(const Model& m) {
  py::dict d;
  const auto specs = m.paramSpecs();
  const auto p = m.params();
  for (size_t i = 0; i < specs.size(); ++i) d[py::str(specs[i].name)] = p[i];
  return d;
}

void setParameters(Model& m, const py::dict& d) {
  const auto specs = m.paramSpecs();
  auto p = m.params();
  for (const auto& [k, v] : d) {
    const std::string name = py::str(k);
    size_t i = 0;
    while (i < specs.size() && specs[i].name != name) ++i;
    if (i == specs.size())
      throw std::invalid_argument("parameters: '" + name + "' is not a parameter of " + m.describe());
    p[i] = v.cast<double>();
  }
  m.setParams(p);
}

model::OutputForm outputForm(const std::string& name) {
  model::OutputForm f;
  if (!model::parseOutputForm(name, f)) throw std::invalid_argument("output_form: '" + name + "' (aligned, printed)");
  return f;
}

// y into `out` when given (a float64 C-contiguous array as long as u, reused), else into a new array.
using Output = py::array_t<double, py::array::c_style>;  // written to: no forcecast (no copy to write into)
Output simulate(const Model& m, const Array& u, double Ts, const std::optional<Array>& load,
                std::optional<Output> out) {
  if (u.ndim() != 1) throw std::invalid_argument("u: a 1-D array is needed");
  if (load && load->size() != u.size()) throw std::invalid_argument("load: not as long as u");
  if (!(Ts > 0)) throw std::invalid_argument("Ts: must be positive");
  if (out && (out->ndim() != 1 || out->size() != u.size() || !out->writeable()))
    throw std::invalid_argument("out: a writable 1-D float64 array as long as u is needed");
  Output y = out ? *out : Output(u.size());
  if (u.size() == 0) return y;
  const double* l = load ? load->data() : nullptr;
  double* dst = y.mutable_data();
  {
    py::gil_scoped_release free;
    m.simulate(u.data(), l, static_cast<size_t>(u.size()), Ts, dst);
  }
  return y;
}

// The best wall time of `repeats` calls of Model::simulate on u from C++ (python/bench_python.py): into
// a buffer allocated once, or (allocate) into a new vector each call, as a call returning y would.
double simulateSeconds(const Model& m, const Array& u, double Ts, int repeats, bool allocate) {
  const auto n = static_cast<size_t>(u.size());
  std::vector<double> y(n);
  double best = INFINITY;
  py::gil_scoped_release free;
  for (int i = 0; i < repeats; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    if (allocate) {
      std::vector<double> fresh(n);
      m.simulate(u.data(), nullptr, n, Ts, fresh.data());
    } else {
      m.simulate(u.data(), nullptr, n, Ts, y.data());
    }
    best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  }
  return best;
}

}  // namespace

void bindModel(py::module_& mod) {
  bindMeasurement(mod);
  py::class_<Model>(mod, "Model")
      .def(py::init([](const std::vector<std::string>& effects, const std::string& form) {
             Model m;
             m.setOutputForm(outputForm(form));
             for (const auto& e : effects) m.addEffect(e);
             return m;
           }),
           py::arg("effects") = std::vector<std::string>{}, py::arg("output_form") = "aligned")
      .def_static(
          "load",
          [](const py::object& p) {
            const std::string path = pathOf(p);
            return readingFile(path, [&] { return io::readModelFile(path); });
          },
          py::arg("path"))
      .def(
          "save",
          [](const Model& m, const py::object& p, const py::object& fit) {
            io::writeModelFile(pathOf(p), m, fit.is_none() ? nlohmann::json{} : fromPython(fit));
          },
          py::arg("path"), py::arg("fit") = py::none())
      .def_static(
          "from_dict", [](const py::object& d) { return io::modelFromJson(fromPython(d), "dict"); }, py::arg("d"))
      .def("to_dict", [](const Model& m) { return toPython(io::modelToJson(m)); })
      .def_property("parameters", &parameters, &setParameters)
      .def_property_readonly("effects", &Model::effectNames)
      .def_property_readonly("output_form", [](const Model& m) { return model::outputFormName(m.outputForm()); })
      .def("simulate", &simulate, py::arg("u"), py::arg("Ts") = 1e-3, py::arg("load") = py::none(),
           py::arg("out") = py::none())
      .def("describe", &Model::describe)
      .def("copy", [](const Model& m) { return Model(m); })
      .def("__copy__", [](const Model& m) { return Model(m); })
      .def("__deepcopy__", [](const Model& m, const py::dict&) { return Model(m); })
      .def("__repr__", [](const Model& m) { return "<pamc.Model " + m.describe() + ">"; });
  mod.def("_simulate_seconds", &simulateSeconds, py::arg("model"), py::arg("u"), py::arg("Ts"), py::arg("repeats"),
          py::arg("allocate"));
}

}  // namespace pamc::python
