#include "app/command.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "io/measurement.hpp"
#include "io/text.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"
#include "control/trajectory.hpp"

namespace pamc::app {
namespace {

// pamc emulate: excite the emulator open loop and write a measurement.
class EmulateCommand final : public Command {
 public:
  explicit EmulateCommand(CLI::App& app)
      : Command(app.add_subcommand("emulate", "excite the plant emulator open loop and write a measurement CSV")) {
    cmd_->add_option(
            "--input", em_input,
            "command u(t) [V]: " + control::Trajectory::forms() + " (docs/MODELING.md, \"Designing a record\")")
        ->capture_default_str();
    cmd_->add_option("--input-from", em_input_from,
                     "replay the command (and a 'load' column, if any) of this measurement CSV instead of --input; "
                     "its sample time must be the plant's")
        ->excludes("--input");
    cmd_->add_option("--duration", em_duration, "seconds")->capture_default_str()->check(CLI::PositiveNumber);
    cmd_->add_option("--plant", em_plant, "plant file (JSON; default: the physics plant, `pamc plant` shows it)");
    cmd_->add_option("--load", em_load, "external force [N] over time, same forms as --input (adds a 'load' column)");
    cmd_->add_option("--out", em_out, "measurement CSV to write (t,u,y,p)")->required();
  }
  int run() override {
    plant::PlantConfig pc = em_plant.empty() ? plant::PlantConfig::defaults() : plant::PlantConfig::fromFile(em_plant);
    plant::Plant p(pc);
    if (!em_input_from.empty()) return replay(p);
    const auto traj = control::Trajectory::parse(em_input);
    control::Trajectory force;
    if (!em_load.empty()) force = control::Trajectory::parse(em_load);
    const auto r = sim::runOpenLoopInput(p, traj, em_duration, em_load.empty() ? nullptr : &force);
    if (em_load.empty())
      io::writeCsvAtomic(em_out, {"t", "u", "y", "p"}, {&r.t, &r.u, &r.y, &r.p});
    else
      io::writeCsvAtomic(em_out, {"t", "u", "y", "p", "load"}, {&r.t, &r.u, &r.y, &r.p, &r.force});
    std::printf("wrote %s: %zu samples of u = %s\n", em_out.c_str(), r.t.size(), traj.describe().c_str());
    return 0;
  }

 private:
  // --input-from: the recorded command through this plant, sample by sample.
  int replay(plant::Plant& p) {
    std::vector<std::string> warnings;
    const io::Measurement m = io::readMeasurementCsv(em_input_from, &warnings);
    printWarnings(warnings);
    if (std::fabs(m.Ts - p.config().Ts) > 1e-9 * p.config().Ts)
      throw io::InputError(em_input_from + ": sample time " + io::fmt("%g", m.Ts) + " s, the plant's is " +
                           io::fmt("%g", p.config().Ts) + " s");
    const auto* load = m.column("load");
    const auto r = sim::runOpenLoopSamples(p, m.u, load);
    if (load)
      io::writeCsvAtomic(em_out, {"t", "u", "y", "p", "load"}, {&r.t, &r.u, &r.y, &r.p, &r.force});
    else
      io::writeCsvAtomic(em_out, {"t", "u", "y", "p"}, {&r.t, &r.u, &r.y, &r.p});
    std::printf("wrote %s: %zu samples of the command of %s\n", em_out.c_str(), r.t.size(), em_input_from.c_str());
    return 0;
  }

  std::string em_input = "sine:0.1:0.2:2.9", em_input_from, em_out, em_plant, em_load;
  double em_duration = 40.0;
};

}  // namespace

std::unique_ptr<Command> makeEmulateCommand(CLI::App& app) { return std::make_unique<EmulateCommand>(app); }

}  // namespace pamc::app
