#include "app/command.hpp"

#include <cstdio>

#include "plant/plant.hpp"

namespace pamc::app {
namespace {

// pamc plant: the emulator's configuration (the defaults of its kind merged with a file).
class PlantCommand final : public Command {
 public:
  explicit PlantCommand(CLI::App& app) : Command(app.add_subcommand("plant", "show the plant emulator's configuration")) {
    cmd_->add_option("--plant", file_, "plant file to load and show merged with the defaults of its kind "
                                        "(\"kind\": \"physics\", the default, or \"model\")");
    addOldSpelling(cmd_, "--config", "--plant", file_);
    cmd_->add_flag("--model-kind", model_kind_, "without --plant: the defaults of the model kind");
  }
  int run() override {
    const auto c = !file_.empty() ? plant::PlantConfig::fromFile(file_)
                   : model_kind_  ? plant::PlantConfig::modelDefaults()
                                  : plant::PlantConfig::defaults();
    std::printf("%s\n", c.toJson().dump(2).c_str());
    return 0;
  }

 private:
  std::string file_;
  bool model_kind_ = false;
};

}  // namespace

std::unique_ptr<Command> makePlantCommand(CLI::App& app) { return std::make_unique<PlantCommand>(app); }

}  // namespace pamc::app
