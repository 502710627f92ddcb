#include "app/command.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

#include "io/measurement.hpp"
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
    cmd_->add_option("--input", em_input, "command u(t) [V]: sine:F:OFFSET:AMP, triangle:F:LO:HI, square:F:LO:HI, "
                                          "chirp:F0:F1:OFFSET:AMP:DURATION, random:SEED:LO:HI, ...")
        ->capture_default_str();
    cmd_->add_option("--duration", em_duration, "seconds")->capture_default_str()->check(CLI::PositiveNumber);
    cmd_->add_option("--plant", em_plant, "plant emulator config (JSON)");
    cmd_->add_option("--load", em_load, "external force [N] over time, same forms as --input (adds a 'load' column)");
    cmd_->add_option("--out", em_out, "measurement CSV to write (t,u,y,p)")->required();
  }
  int run() override {
    plant::PlantConfig pc = em_plant.empty() ? plant::PlantConfig::defaults() : plant::PlantConfig::fromFile(em_plant);
    plant::Plant p(pc);
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
  std::string em_input = "sine:0.1:0.2:2.9", em_out, em_plant, em_load;
  double em_duration = 40.0;
};

}  // namespace

std::unique_ptr<Command> makeEmulateCommand(CLI::App& app) { return std::make_unique<EmulateCommand>(app); }

}  // namespace pamc::app
