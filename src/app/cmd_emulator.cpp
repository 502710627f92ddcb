#include "app/command.hpp"

#include <fcntl.h>
#include <time.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "app/bus_common.hpp"
#include "app/controller_options.hpp"
#include "app/node_options.hpp"
#include "io/measurement.hpp"
#include "nodes/decoder.hpp"
#include "nodes/monitor.hpp"
#include "nodes/rig_file.hpp"
#include "rig/fault_rig.hpp"
#include "rig/rig_emulator.hpp"
#include "rig/virtual_rig.hpp"

namespace pamc::app {
namespace {

// pamc emulator: the sensor and valve nodes with the emulator's physics on a SocketCAN interface.
class EmulatorCommand final : public Command {
 public:
  explicit EmulatorCommand(CLI::App& app)
      : Command(
            app.add_subcommand("emulator", "play the valve and sensor nodes with the emulator physics on SocketCAN")) {
    iface_.add(cmd_, false);
    od_.add(cmd_);
    cmd_->add_option("--rig", rig_,
                     "play the devices of this rig file (a rig of several channels: an encoder per "
                     "channel and the valve module with an output per channel, od/rigs/four_muscles.ini)");
    emu_.add(cmd_);
    cmd_->add_option("--duration", emu_duration, "stop after this many seconds of SYNCs (0: until Ctrl-C)")
        ->capture_default_str()
        ->check(CLI::NonNegativeNumber);
    cmd_->add_option("--period-us", period_us, "SYNC period the physics steps by (default 1000 us)")
        ->check(CLI::Range(100u, 1000000u));
    cmd_->add_option("--log", candump, "write every frame to this file as a candump -l log");
    rt_.add(cmd_, "real time");
  }
  int run() override {
    nodes::EmulatorConfig ec = emu_.config(od_.dir, period_us);
    if (!rig_.empty()) ec = rig::emulatorOf(readRig(rig_), ec);
    const std::string iface = iface_.resolve("");
    realtimeSetup(rt_.rt, rt_.cpu, rt_.priority);
    auto canp = openCan(iface);
    auto& can = *canp;
    auto emup = std::make_unique<nodes::EmulatorNodes>(ec, can);
    auto& emu = *emup;
    auto loggerp = std::make_unique<Logger>(candump, iface, "", period_us);
    auto& logger = *loggerp;
    can.setTap([&](const canopen::Frame& f, canopen::TimeUs t, bool) { logger.frames.push({f, t}); });
    canopen::EventLoop loop(can, emu);
    g_loop = &loop;
    installSignals();
    logger.start();
    std::fprintf(stderr, "emulator on %s: %zu muscle%s, sensor node%s", iface.c_str(), emu.channels(),
                 emu.channels() > 1 ? "s" : "", emu.sensors() > 1 ? "s" : "");
    for (std::size_t s = 0; s < emu.sensors(); ++s)
      std::fprintf(stderr, "%s%u", s ? ", " : " ", emu.sensor(s).nodeId());
    std::fprintf(stderr, ", valve node%s", emu.valveModules() > 1 ? "s" : "");
    for (std::size_t m = 0; m < emu.valveModules(); ++m)
      std::fprintf(stderr, "%s%u", m ? ", " : " ", emu.valve(m).nodeId());
    std::fprintf(stderr, "; stepped by SYNC\n");
    std::thread watch([&] {
      while (!g_stop) {
        std::this_thread::sleep_for(std::chrono::milliseconds(50));
        if (emu_duration > 0 && emu.time() >= emu_duration) loop.stop();
      }
    });
    {
      Joiner j{watch};
      emu.start(canopen::monotonicNowUs());
      loop.run();
    }
    g_loop = nullptr;
    logger.stop();
    std::printf("emulated %.3f s (%llu position PDOs dropped by fault injection)\n", emu.time(),
                static_cast<unsigned long long>(emu.pdosDropped()));
    return 0;
  }

 private:
  std::string candump, rig_;
  InterfaceOption iface_;
  double emu_duration = 0.0;
  unsigned period_us = 0;
  OdOption od_;
  EmulatorOptions emu_;
  RealtimeOptions rt_;
};

}  // namespace

std::unique_ptr<Command> makeEmulatorCommand(CLI::App& app) { return std::make_unique<EmulatorCommand>(app); }

}  // namespace pamc::app
