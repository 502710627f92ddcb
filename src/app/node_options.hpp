// Option groups of the commands that run the controller node (rig, controller).
#pragma once

#include <CLI/CLI.hpp>

#include <cstdio>
#include <string>

#include "app/bus_common.hpp"
#include "app/controller_options.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/rig_file.hpp"
#include "control/actuation.hpp"
#include "control/trajectory.hpp"
#include "io/text.hpp"

namespace pamc::app {

// The run of a controller node: its trajectory (or an open-loop input in place of trajectory and
// controller), how long, the cycle records, the measurement, the SYNC period.
struct NodeRunOptions {
  std::string trajectory = "triangle:0.05:0.2:30";
  std::string input;  // --input: the valve command u(t), no controller
  double duration = 40.0, preroll = 5.0;
  std::string csv, out;
  unsigned period_us = 0;
  bool openLoopInput() const { return !input.empty(); }
  // Call after --controller is added (--input excludes it).
  void add(CLI::App* a) {
    auto* traj = a->add_option("--trajectory", trajectory,
                               "desired position: triangle:F:LO:HI, sinedesc:F:C:A0:A1:T, square:F:LO:HI, ...")
                     ->capture_default_str();
    auto* in = a->add_option("--input", input, inputHelp())->excludes(traj);
    if (auto* kind = a->get_option_no_throw("--controller")) in->excludes(kind);
    a->add_option("--out", out,
                  "measurement CSV to write at the end (t,u,y,p - p where the rig maps a pressure): "
                  "from the first cycle after the pre-roll, u the command that went to the valve, y the "
                  "sensor's position; written whole or not at all");
    a->add_option(
         "--duration", duration,
         "seconds of trajectory; the run ends by the clock at the latest pre-roll + duration + 3 s after the start, "
         "whatever the slaves do (0: until stopped with Ctrl-C)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    a->add_option("--preroll", preroll, "seconds holding the first setpoint before the trajectory")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    a->add_option("--csv", csv, "file for the cycle records (t,yd,y,u,...)");
    a->add_option("--period-us", period_us, "SYNC period (default: 0x1006 of the EDS, 1000 us)")
        ->check(CLI::Range(100u, 1000000u));
  }
  static std::string inputHelp() {
    return "open loop for identification, in place of --trajectory and the controller: the valve command u(t) [V "
           "about the valve's mid-range], passed through within [" +
           io::fmt("%g", control::kCommandMin) + ", " + io::fmt("%g", control::kCommandMax) +
           "] (a fault still sends the safe value; the pre-roll holds u(0)): " + control::Trajectory::forms();
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

// --input's spec (one line naming the option and the spec when it is not one).
inline control::Trajectory parseInput(const std::string& spec) {
  try {
    return control::Trajectory::parse(spec);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string("--input: ") + e.what());
  }
}

// The controller node's configuration from the option groups.
inline nodes::ControllerNodeConfig controllerNodeConfig(const OdOption& od, const ControllerKindOption& kind,
                                                        const ControllerOptions& ctrl, const NodeRunOptions& run,
                                                        bool consume_sync, const RigOption* rig = nullptr) {
  nodes::ControllerNodeConfig c;
  c.eds_path = od.dir + "/controller.eds";
  c.kind = static_cast<int>(run.openLoopInput() ? control::Kind::Input : kind.kind());
  c.ctrl = ctrl.config();
  c.delay_cycles = ctrl.cc.delay_cycles;
  c.gains_from_config = true;
  c.has_trajectory = true;
  c.trajectory = run.openLoopInput() ? parseInput(run.input) : control::Trajectory::parse(run.trajectory);
  c.preroll_s = run.preroll;
  c.produce_sync = !consume_sync;
  c.period_us = run.period_us;
  if (rig != nullptr && rig->given()) {
    nodes::applyRig(readRig(rig->path), c);
    if (run.period_us) c.period_us = run.period_us;
  }
  c.log = [](const std::string& m) { std::fprintf(stderr, "%s\n", m.c_str()); };
  if (c.kind >= 0 && control::usesModel(static_cast<control::Kind>(c.kind)) && ctrl.model_file.empty())
    std::fprintf(stderr, "warning: no --model: the %s controller uses the model parameters of the EDS defaults\n",
                 kind.name.c_str());
  return c;
}

// --out: the logger's records into the measurement too; with --input no tracking error is summed.
inline void attachMeasurement(Logger& logger, MeasurementRecord& m, const NodeRunOptions& run) {
  logger.summary.open_loop_input = run.openLoopInput();
  if (!run.out.empty()) logger.measurement = &m;
}

// --out written at the end of the run (atomically; nothing when it cannot be a whole record).
inline void writeMeasurement(const MeasurementRecord& m, const std::string& out) {
  if (out.empty()) return;
  m.write(out);
  std::printf("wrote %s: %zu samples", out.c_str(), m.size());
  if (m.faultCycles() > 0)
    std::printf(", %llu of them in a fault (u: the safe value)", static_cast<unsigned long long>(m.faultCycles()));
  std::printf("\n");
}

}  // namespace pamc::app
