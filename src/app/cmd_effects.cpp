#include "app/command.hpp"

#include <cstdio>

#include "model/effect.hpp"
#include "model/probe.hpp"

namespace pamc::app {
namespace {

// pamc effects: the catalogue of physical effects.
class EffectsCommand final : public Command {
 public:
  explicit EffectsCommand(CLI::App& app)
      : Command(app.add_subcommand("effects", "list the catalogue of physical effects")) {
    cmd_->add_flag("--probes", probes_,
                   "list the probes instead: generic structures diagnose tries when no effect explains the residual");
  }
  int run() override {
    if (probes_) {
      for (const auto& e : model::probes()) {
        print(e.name, *e.make());
        std::printf("%-20s   points to: %s\n", "", e.meaning);
      }
      return 0;
    }
    for (const auto& e : model::catalogue()) print(e.name, *e.make());
    return 0;
  }

 private:
  static void print(const char* name, const model::Effect& x) {
    std::printf("%-20s %s %s\n", name, x.stage() == model::Stage::Input ? "[input] " : "[output]", x.explanation());
    for (const auto& p : x.params())
      std::printf("%-20s   %-12s default %-10g bounds [%g, %g] %s\n", "", p.name.c_str(), p.def, p.lo, p.hi,
                  p.unit.c_str());
  }
  bool probes_ = false;
};

}  // namespace

std::unique_ptr<Command> makeEffectsCommand(CLI::App& app) { return std::make_unique<EffectsCommand>(app); }

}  // namespace pamc::app
