// One subcommand of pamc per file (cmd_<name>.cpp): its constructor adds the subcommand and its
// options to the app, run() does the work once the command line is parsed. commands.cpp lists them.
#pragma once

#include <CLI/CLI.hpp>

#include <memory>
#include <string>
#include <vector>

#include "model/model.hpp"

namespace pamc::app {

class Command {
 public:
  explicit Command(CLI::App* cmd) : cmd_(cmd) {}
  virtual ~Command() = default;
  Command(const Command&) = delete;
  Command& operator=(const Command&) = delete;
  bool selected() const { return cmd_->parsed(); }
  virtual int run() = 0;

 protected:
  CLI::App* cmd_;
};

using CommandFactory = std::unique_ptr<Command> (*)(CLI::App&);

// The modelling side.
std::unique_ptr<Command> makeExperimentsCommand(CLI::App& app);
std::unique_ptr<Command> makeRobustnessCommand(CLI::App& app);
std::unique_ptr<Command> makeCalibrateCommand(CLI::App& app);
std::unique_ptr<Command> makeFitCommand(CLI::App& app);
std::unique_ptr<Command> makeCompareCommand(CLI::App& app);
std::unique_ptr<Command> makeDiagnoseCommand(CLI::App& app);
std::unique_ptr<Command> makeEmulateCommand(CLI::App& app);
std::unique_ptr<Command> makePlantCommand(CLI::App& app);
std::unique_ptr<Command> makeEffectsCommand(CLI::App& app);
// The bus side.
std::unique_ptr<Command> makeRigCommand(CLI::App& app);
std::unique_ptr<Command> makeControllerCommand(CLI::App& app);
std::unique_ptr<Command> makeEmulatorCommand(CLI::App& app);
std::unique_ptr<Command> makeDecodeCommand(CLI::App& app);
std::unique_ptr<Command> makeMonitorCommand(CLI::App& app);

// In the order `pamc --help` lists them.
inline const CommandFactory kCommands[] = {
    makeExperimentsCommand, makeRobustnessCommand, makeCalibrateCommand, makeFitCommand,     makeCompareCommand,
    makeDiagnoseCommand,    makeEmulateCommand,    makePlantCommand,     makeEffectsCommand, makeRigCommand,
    makeControllerCommand,  makeEmulatorCommand,   makeDecodeCommand,    makeMonitorCommand};

// Old spellings of options, kept until version kOldSpellingsUntil (docs/CLI.md): hidden from --help, bound
// to the same variable as the new spelling, one line on stderr when used.
inline constexpr const char* kOldSpellingsUntil = "0.3.0";
void oldSpellingNotice(const std::string& old_usage, const std::string& new_usage);
int oldSpellingNotices();  // how many were printed
// "rig run": the subcommand words of cmd.
std::string commandPath(const CLI::App* cmd);
template <class T>
CLI::Option* addOldSpelling(CLI::App* cmd, const std::string& old_name, const std::string& new_name, T& var) {
  const std::string where = commandPath(cmd) + " ";
  return cmd->add_option(old_name, var)->group("")->each([where, old_name, new_name](const std::string&) {
    oldSpellingNotice(where + old_name, where + new_name);
  });
}
CLI::Option* addOldFlag(CLI::App* cmd, const std::string& old_name, const std::string& new_usage, bool& var);

// --output-form: the form a model is fitted in (model::OutputForm), the same option wherever a model is fitted.
CLI::Option* addOutputFormOption(CLI::App* cmd, std::string& form);
model::OutputForm outputFormOf(const std::string& form);

std::vector<std::string> splitList(const std::string& s);
void progressLine(const std::string& m);
// Every warning a reader or writer appended, one "warning: ..." line each on stderr; then empties the list.
void printWarnings(std::vector<std::string>& warnings);

}  // namespace pamc::app
