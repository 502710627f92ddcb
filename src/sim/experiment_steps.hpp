// The steps of runExperiments (experiments.cpp), one function per experiment, sharing one context.
// Private to src/sim.
#pragma once

#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "control/controller.hpp"
#include "sim/experiments.hpp"
#include "sim/lockstep.hpp"

namespace pamc::sim::detail {

// What every experiment needs: the settings, the output folder, the identified model and the
// controller configuration built on it, and the text and JSON of the summary being written.
struct Context {
  const ExperimentSettings& s;
  std::string dir;  // with a trailing '/'
  bool figures = false;
  std::ostringstream txt;
  nlohmann::json json;
  model::Model ref;
  control::ControllerConfig cc;
  control::InverseStatic inv;
  std::string readings_line;  // the readings, for figure titles

  explicit Context(const ExperimentSettings& settings) : s(settings) {}
  void log(const std::string& m) const;
  void warn(const std::string& m) const { log("warning: " + m); }
  // One closed-loop run of `kind` with the context's configuration (or `c`), written to dir/<tag>_<kind>.csv.
  Record run(control::Kind kind, const ClosedLoopRun& run, const std::string& tag,
             const control::ControllerConfig* c = nullptr, const std::string& csv_name = "") const;
};

void runTable1(Context& x);
void useModel(Context& x);     // the model file without Table 1's records
void runTriangle(Context& x);  // Table 2's triangle row alone
void buildController(Context& x);
void runTable2(Context& x);
void runDiscontinuous(Context& x);
void runPayload(Context& x);

// Figures (experiment_figures.cpp). Colours are fixed per controller across every figure.
const char* label(control::Kind k);
const char* colour(control::Kind k);
void figureTracking(const Context& x, const std::string& tag, const std::string& title,
                    const std::vector<control::Kind>& kinds, bool steps = false);
void figurePayload(const Context& x, const std::string& tag, const std::string& title,
                   const std::vector<control::Kind>& kinds, double t_event);
void figureTable1(const Context& x, const std::string& csv, const std::string& png, const std::string& title);

// The reading texts (summary and figure titles).
std::string esoText(const control::ControllerConfig& c);
std::string gainsText(const control::ControllerConfig& c);
std::string plantText(const plant::PlantConfig& p);

}  // namespace pamc::sim::detail
