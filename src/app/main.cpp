// pamc: command-line front end. One file per subcommand (cmd_<name>.cpp); the table is in command.hpp.
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <vector>

#include "app/command.hpp"
#include "app/completion.hpp"
#include "io/measurement.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "pamc - pneumatic artificial muscle control: Bouc-Wen model, GA identification, UKF active "
      "model control, plant emulator, CANopen nodes"};
  app.require_subcommand(1);
  // A command line that does not parse gets one line, as any other bad input does.
  app.failure_message(
      [](const CLI::App*, const CLI::Error& e) { return "pamc: error: " + std::string(e.what()) + "\n"; });
  // For the command-line test: parse (options, values, checks) and stop before running anything.
  bool parse_only = false;
  app.add_flag("--parse-only", parse_only, "parse the command line and exit")->group("");
  std::vector<std::unique_ptr<pamc::app::Command>> commands;
  for (auto make : pamc::app::kCommands) commands.push_back(make(app));
  // For the build: the bash completion from these option tables (app/completion.hpp).
  if ((argc == 2 || argc == 3) && std::strcmp(argv[1], "--bash-completion") == 0) {
    const std::string script = pamc::app::bashCompletion(app);
    if (argc == 2) return std::fputs(script.c_str(), stdout) < 0 ? 1 : 0;
    try {
      pamc::io::writeFileAtomic(argv[2], script);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "pamc: error: %s\n", e.what());
      return 1;
    }
    return 0;
  }
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
