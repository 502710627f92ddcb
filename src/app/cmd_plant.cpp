#include "app/command.hpp"

#include <cstdio>

#include "plant/plant.hpp"
#include "sim/experiments.hpp"

namespace pamc::app {
namespace {

// pamc plant: the emulator's configuration (the defaults of its kind merged with a file).
class PlantCommand final : public Command {
 public:
  explicit PlantCommand(CLI::App& app)
      : Command(app.add_subcommand("plant", "show the plant emulator's configuration")) {
    auto* file = cmd_->add_option("--plant", file_,
                                  "plant file to load and show merged with the defaults of its kind "
                                  "(\"kind\": \"physics\", the default, or \"model\")");
    addOldSpelling(cmd_, "--config", "--plant", file_);
    auto* mk = cmd_->add_flag("--model-kind", model_kind_, "without --plant: the defaults of the model kind");
    cmd_->add_flag("--calibrated", calibrated_,
                   "without --plant: the calibrated physics plant `pamc experiments` and `pamc robustness` run on "
                   "(docs/CALIBRATION.md), to emulate records on with `pamc emulate --plant`")
        ->excludes(mk)
        ->excludes(file);
  }
  int run() override {
    const auto c = !file_.empty() ? plant::PlantConfig::fromFile(file_)
                   : model_kind_  ? plant::PlantConfig::modelDefaults()
                   : calibrated_  ? sim::paperPlant()
                                  : plant::PlantConfig::defaults();
    std::printf("%s\n", c.toJson().dump(2).c_str());
    return 0;
  }

 private:
  std::string file_;
  bool model_kind_ = false;
  bool calibrated_ = false;
};

}  // namespace

std::unique_ptr<Command> makePlantCommand(CLI::App& app) { return std::make_unique<PlantCommand>(app); }

}  // namespace pamc::app
