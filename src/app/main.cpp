// pamc: command-line front end. One file per subcommand (cmd_<name>.cpp); the table is in command.hpp.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <memory>
#include <vector>

#include "app/command.hpp"

int main(int argc, char** argv) {
  CLI::App app{"pamc - pneumatic artificial muscle control: Bouc-Wen model, GA identification, UKF active "
               "model control, plant emulator, CANopen nodes"};
  app.require_subcommand(1);
  // For the command-line test: parse (options, values, checks) and stop before running anything.
  bool parse_only = false;
  app.add_flag("--parse-only", parse_only, "parse the command line and exit")->group("");
  std::vector<std::unique_ptr<pamc::app::Command>> commands;
  for (auto make : pamc::app::kCommands) commands.push_back(make(app));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  if (parse_only) return 0;
  try {
    for (auto& c : commands)
      if (c->selected()) return c->run();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "pamc: error: %s\n", e.what());
    return 1;
  }
  return 0;
}
