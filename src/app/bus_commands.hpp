// The CANopen side of the command line: controller and emulator nodes on SocketCAN, the same rig
// on the in-process bus, candump logs decoded into measurements, and a live bus monitor.
#pragma once

#include <CLI/CLI.hpp>

#include <memory>

namespace pamc::app {

class BusCommands {
 public:
  explicit BusCommands(CLI::App& app);
  ~BusCommands();
  BusCommands(const BusCommands&) = delete;
  BusCommands& operator=(const BusCommands&) = delete;
  // Runs the chosen subcommand; returns -1 if none of them was chosen.
  int run();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace pamc::app
