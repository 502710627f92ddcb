// The controller's options, one struct shared by every command that builds a controller
// (experiments, rig, controller): gains, the reading of eq. (17), the predictive AMC, the ESO, the
// delay and the model file. Defaults are control::ControllerConfig's (the gains: control::kDefaultGains).
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "control/controller.hpp"

namespace pamc::app {

struct ControllerOptions {
  control::ControllerConfig cc;
  std::string amc_form = "printed";
  std::string eso_form = cc.eso.order == 2 ? "printed" : "first-order";
  std::string model_file;
  // with_model: --model (the experiments identify their own model unless given one).
  void add(CLI::App* a);
  // Only the three gains (the fault tools, which set up the rest themselves).
  void addGains(CLI::App* a);
  // The rest: the reading of eq. (17), the predictive AMC, the ESO, the delay, the model file.
  void addStructure(CLI::App* a);
  // The configuration with the model file read (throws with the file's one-line error).
  control::ControllerConfig config() const;
  // The paper's experiments (experiments, robustness): config() without the model (they read or identify
  // it themselves).
  control::ControllerConfig paperConfig() const;
};

// --controller: open, pi (pid: the paper's "PID" is a PI), eso, amc.
struct ControllerKindOption {
  std::string name = "pi";
  void add(CLI::App* a);
  control::Kind kind() const { return control::kindFromString(name); }
};

}  // namespace pamc::app
