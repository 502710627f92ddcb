// The bash completion of pamc, generated from the same option tables as its --help (CLI11 makes none):
// `pamc --bash-completion` prints it; the build writes it to pamc.bash, installed as
// share/bash-completion/completions/pamc.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

namespace pamc::app {

std::string bashCompletion(const CLI::App& app);

}  // namespace pamc::app
