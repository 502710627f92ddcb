#include "app/command.hpp"

#include <cstdio>

#include "plant/plant.hpp"

namespace pamc::app {
namespace {

// pamc plant: the emulator's configuration (defaults merged with a file).
class PlantCommand final : public Command {
 public:
  explicit PlantCommand(CLI::App& app) : Command(app.add_subcommand("plant", "show the plant emulator's configuration")) {
    cmd_->add_option("--config", file_, "config file to load and show merged with the defaults");
  }
  int run() override {
    const auto c = file_.empty() ? plant::PlantConfig::defaults() : plant::PlantConfig::fromFile(file_);
    std::printf("%s\n", c.toJson().dump(2).c_str());
    return 0;
  }

 private:
  std::string file_;
};

}  // namespace

std::unique_ptr<Command> makePlantCommand(CLI::App& app) { return std::make_unique<PlantCommand>(app); }

}  // namespace pamc::app
