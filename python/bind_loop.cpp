// The closed loop from Python: trajectories, the plant emulator and the controllers, each stepped one
// sample at a time, and the library's lockstep loop (sim::runClosedLoop) to compare with.
#include <pybind11/stl.h>

#include "bind.hpp"
#include "control/trajectory.hpp"
#include "convert.hpp"
#include "io/controller_settings.hpp"
#include "io/model_file.hpp"
#include "sim/lockstep.hpp"

namespace pamc::python {

plant::PlantConfig plantConfigOf(const py::handle& p) {
  if (p.is_none()) return plant::PlantConfig::defaults();
  if (py::isinstance<py::dict>(p)) return plant::PlantConfig::fromJson(fromPython(p), "dict");
  const std::string path = pathOf(p);
  return readingFile(path, [&] { return plant::PlantConfig::fromFile(path); });
}

using control::ControllerConfig;

void applyControllerSettings(ControllerConfig& c, const py::dict& settings) {
  for (const auto& [k, v] : settings) {
    const std::string name = py::str(k);
    if (name == "model")
      c.model = py::isinstance<model::Model>(v) ? v.cast<model::Model>() : [&] {
        const std::string path = pathOf(v);
        return readingFile(path, [&] { return io::readModelFile(path); });
      }();
    else if (!io::setControllerSetting(c, name, fromPython(v)))
      throw py::type_error("unknown controller setting '" + name + "'");
  }
}

namespace {

// A controller of the library with its configuration and the parts of its last command.
struct PyController {
  ControllerConfig config;
  std::unique_ptr<control::Controller> impl;
  control::ControlOutput last;
};

PyController makeController(const std::string& kind, const py::kwargs& settings) {
  PyController c;
  applyControllerSettings(c.config, settings);
  c.impl = control::makeController(control::kindFromString(kind), c.config);
  return c;
}

py::dict lastOutput(const control::ControlOutput& o) {
  py::dict d;
  d["u"] = o.u, d["u_n"] = o.u_n, d["u_c"] = o.u_c, d["y_hat"] = o.y_hat, d["saturated"] = o.saturated;
  d["estimator_reset"] = o.estimator_reset, d["measurement_rejected"] = o.measurement_rejected;
  d["model_distrusted"] = o.model_distrusted, d["model_ratio"] = o.model_ratio;
  return d;
}

py::dict recordDict(sim::Record&& r) {
  const auto stats = sim::tracking(r);
  py::dict d;
  d["rmse"] = stats.rmse, d["max_abs"] = stats.max_abs;
  d["t"] = toArray(std::move(r.t)), d["yd"] = toArray(std::move(r.yd)), d["y"] = toArray(std::move(r.y));
  d["y_true"] = toArray(std::move(r.y_true)), d["u"] = toArray(std::move(r.u)), d["u_n"] = toArray(std::move(r.u_n));
  d["u_c"] = toArray(std::move(r.u_c)), d["y_hat"] = toArray(std::move(r.y_hat));
  d["load"] = toArray(std::move(r.force)), d["p"] = toArray(std::move(r.p));
  return d;
}

py::dict closedLoop(PyController& c, plant::Plant& p, const control::Trajectory& ref, double duration, double u0,
                    double preroll, const std::optional<double>& home) {
  sim::ClosedLoopRun run;
  run.reference = ref;
  run.duration_s = duration;
  run.preroll_s = preroll;
  run.delay_cycles = c.config.delay_cycles;
  if (home) run.home_mm = *home;
  sim::Record r;
  {
    py::gil_scoped_release free;
    r = sim::runClosedLoop(*c.impl, p, run, u0);
  }
  return recordDict(std::move(r));
}

void bindTrajectory(py::module_& m) {
  py::class_<control::Trajectory>(m, "Trajectory")
      .def(py::init(&control::Trajectory::parse), py::arg("spec"))
      .def("at", &control::Trajectory::at, py::arg("t"))
      .def(
          "__call__",
          [](const control::Trajectory& tr, const Array& t) {
            std::vector<double> v = toVector(t, "t");
            for (double& x : v) x = tr.at(x);
            return toArray(std::move(v));
          },
          py::arg("t"))
      .def("describe", &control::Trajectory::describe)
      .def("__repr__", [](const control::Trajectory& tr) { return "<pamc.Trajectory " + tr.describe() + ">"; });
}

void bindPlant(py::module_& m) {
  py::class_<plant::Plant>(m, "Plant")
      .def(py::init([](const py::object& p) { return std::make_unique<plant::Plant>(plantConfigOf(p)); }),
           py::arg("plant") = py::none())
      .def("reset", &plant::Plant::reset, py::arg("u0") = 0.0, py::arg("force") = 0.0)
      .def("step", &plant::Plant::step, py::arg("u"), py::arg("force") = 0.0)
      .def("measure", &plant::Plant::measure)
      .def_property_readonly("position", &plant::Plant::position)
      .def_property_readonly("pressure_bar", &plant::Plant::pressure_bar)
      .def_property_readonly("Ts", [](const plant::Plant& p) { return p.config().Ts; })
      .def_property_readonly("config", [](const plant::Plant& p) { return toPython(p.config().toJson()); });
}

void bindController(py::module_& m) {
  py::class_<PyController>(m, "Controller")
      .def(py::init(&makeController), py::arg("kind") = "pi")
      .def_property_readonly("kind", [](const PyController& c) { return control::toString(c.impl->kind()); })
      .def_property_readonly("lookahead", [](const PyController& c) { return c.impl->lookahead(); })
      .def_property_readonly("Ts", [](const PyController& c) { return c.config.Ts; })
      .def_property_readonly("integral", [](const PyController& c) { return c.impl->integral(); })
      .def_property_readonly("last", [](const PyController& c) { return lastOutput(c.last); })
      .def(
          "activate", [](PyController& c, double u0, double y0) { c.impl->activate(u0, y0); }, py::arg("u0"),
          py::arg("y0"))
      .def(
          "update",
          [](PyController& c, double yd, double yd_next, double y, double load) {
            c.last = c.impl->update(yd, yd_next, y, load);
            return c.last.u;
          },
          py::arg("yd"), py::arg("yd_next"), py::arg("y"), py::arg("load") = 0.0);
  m.def("closed_loop", &closedLoop, py::arg("controller"), py::arg("plant"), py::arg("reference"), py::arg("duration"),
        py::arg("u0") = 0.0, py::arg("preroll") = 5.0, py::arg("home") = py::none());
}

}  // namespace

void bindLoop(py::module_& m) {
  bindTrajectory(m);
  bindPlant(m);
  bindController(m);
}

}  // namespace pamc::python
