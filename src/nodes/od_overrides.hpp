// The command line's choices in the controller node's dictionary (controller, gains, model, trajectory,
// period, SYNC): written at the node's construction and again after an NMT reset (which restores the
// dictionary's defaults), so that SDO reads show what runs. Keeps the node's configuration for it. A rig
// file's and a DCF's values are the dictionary's defaults themselves (ControllerNodeConfig::dictionary).
#pragma once

#include "canopen/node.hpp"
#include "nodes/controller_config.hpp"
#include "nodes/controller_parameters.hpp"

namespace pamc::nodes {

class OdOverrides {
 public:
  explicit OdOverrides(const ControllerNodeConfig& cfg) : cfg_(cfg) {}
  void apply(canopen::ObjectDictionary& od, ControllerParameters& params);
  // The trajectory of the command line, where the dictionary cannot hold its shape (chirp, random).
  bool trajectoryOverridden() const noexcept { return traj_override_; }
  const ControllerNodeConfig& config() const noexcept { return cfg_; }

 private:
  ControllerNodeConfig cfg_;
  bool traj_override_ = false;
};

}  // namespace pamc::nodes
