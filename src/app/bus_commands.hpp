// The CANopen side of the command line: controller and emulator nodes on SocketCAN, the same rig
// on the in-process bus, candump logs decoded into measurements, and a live bus monitor.
#pragma once

#include <CLI/CLI.hpp>

namespace pamc::app {

class BusCommands {
 public:
  explicit BusCommands(CLI::App& app);
  // Runs the chosen subcommand; returns -1 if none of them was chosen.
  int run();

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace pamc::app
