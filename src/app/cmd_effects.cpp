#include "app/command.hpp"

#include <cstdio>

#include "model/effect.hpp"

namespace pamc::app {
namespace {

// pamc effects: the catalogue of physical effects.
class EffectsCommand final : public Command {
 public:
  explicit EffectsCommand(CLI::App& app) : Command(app.add_subcommand("effects", "list the catalogue of physical effects")) {}
  int run() override {
    for (const auto& e : model::catalogue()) {
      auto x = e.make();
      std::printf("%-20s %s %s\n", e.name, x->stage() == model::Stage::Input ? "[input] " : "[output]",
                  x->explanation());
      for (const auto& p : x->params())
        std::printf("%-20s   %-12s default %-10g bounds [%g, %g] %s\n", "", p.name.c_str(), p.def, p.lo, p.hi,
                    p.unit.c_str());
    }
    return 0;
  }
};

}  // namespace

std::unique_ptr<Command> makeEffectsCommand(CLI::App& app) { return std::make_unique<EffectsCommand>(app); }

}  // namespace pamc::app
