// The parts of the module, one function each (module.cpp calls them in order).
#pragma once

#include <pybind11/pybind11.h>

namespace pamc::python {

void bindModel(pybind11::module_& m);     // Model, Measurement, read_csv, write_csv (bind_model.cpp)
void bindAnalysis(pybind11::module_& m);  // fit, compare, diagnose, experiments (bind_analysis.cpp)
void bindLoop(pybind11::module_& m);      // Trajectory, Plant, Controller, closed_loop (bind_loop.cpp)
void bindSweep(pybind11::module_& m);     // the robustness sweep's cells and merge (bind_sweep.cpp)

}  // namespace pamc::python

#include "control/controller.hpp"
#include "plant/plant.hpp"

namespace pamc::python {

// A plant file's path, or its content as a dict (plant::PlantConfig::fromJson); None: the default plant.
plant::PlantConfig plantConfigOf(const pybind11::handle& path_or_dict);
// Sets the ControllerConfig fields named by the keywords (kp=0.1, amc_horizon=0, ...): TypeError on a
// name that is not one of them.
void applyControllerSettings(control::ControllerConfig& c, const pybind11::dict& settings);

}  // namespace pamc::python
