// Option groups of the commands that run the controller node (rig, controller).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>

#include "app/bus_common.hpp"
#include "app/controller_options.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/rig_file.hpp"
#include "control/trajectory.hpp"

namespace pamc::app {

// The run of a controller node: its trajectory, how long, the cycle records, the SYNC period.
struct NodeRunOptions {
  std::string trajectory = "triangle:0.05:0.2:30";
  double duration = 40.0, preroll = 5.0;
  std::string csv;
  unsigned period_us = 0;
  void add(CLI::App* a) {
    a->add_option("--trajectory", trajectory,
                  "desired position: triangle:F:LO:HI, sinedesc:F:C:A0:A1:T, square:F:LO:HI, ...")
        ->capture_default_str();
    a->add_option("--duration", duration, "seconds of trajectory; the run ends by the clock at the latest pre-roll + duration + 3 s after the start, "
                  "whatever the slaves do (0: until stopped with Ctrl-C)")->capture_default_str()->check(CLI::NonNegativeNumber);
    a->add_option("--preroll", preroll, "seconds holding the first setpoint before the trajectory")->capture_default_str()->check(CLI::NonNegativeNumber);
    a->add_option("--csv", csv, "file for the cycle records (t,yd,y,u,...)");
    a->add_option("--period-us", period_us, "SYNC period (default: 0x1006 of the EDS, 1000 us)")->check(CLI::Range(100u, 1000000u));
  }
};

// A rig file: the slaves the controller masters - node-IDs, EDS, identity, PDOs, scaling, what to
// write at their boot (docs/RIG.md). Without it, `pamc controller` runs on od/rigs/default.ini and
// `pamc rig` on pamc's own devices with their built-in layout.
struct RigOption {
  std::string path;
  void add(CLI::App* a) {
    a->add_option("--rig", path,
                  "rig file (docs/RIG.md, od/rigs/): node-IDs, EDS files, the slaves' identity, PDOs, scaling and "
                  "boot configuration; its interface and period unless --iface / --period-us are given "
                  "(pamc controller without it: od/rigs/default.ini)");
  }
  bool given() const { return !path.empty(); }
};

// The controller node's configuration from the option groups.
inline nodes::ControllerNodeConfig controllerNodeConfig(const OdOption& od, const ControllerKindOption& kind,
                                                        const ControllerOptions& ctrl, const NodeRunOptions& run,
                                                        bool consume_sync, const RigOption* rig = nullptr) {
  nodes::ControllerNodeConfig c;
  c.eds_path = od.dir + "/controller.eds";
  c.kind = static_cast<int>(kind.kind());
  c.ctrl = ctrl.config();
  c.delay_cycles = ctrl.cc.delay_cycles;
  c.gains_from_config = true;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::parse(run.trajectory);
  c.preroll_s = run.preroll;
  c.produce_sync = !consume_sync;
  c.period_us = run.period_us;
  if (rig != nullptr && rig->given()) {
    nodes::applyRig(nodes::readRigFile(rig->path), c);
    if (run.period_us) c.period_us = run.period_us;
  }
  c.log = [](const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); };
  if ((c.kind == static_cast<int>(control::Kind::PiAmc) || c.kind == static_cast<int>(control::Kind::OpenLoop)) &&
      ctrl.model_file.empty())
    std::fprintf(stderr, "warning: no --model: the %s controller uses the model parameters of the EDS defaults\n",
                 kind.name.c_str());
  return c;
}

}  // namespace pamc::app
