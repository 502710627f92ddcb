// Controller node and emulator nodes on the in-process bus in virtual time: the whole rig, every
// frame through the CANopen layer, deterministic and faster than real time.
#pragma once

#include <string>
#include <vector>

#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"

namespace pamc::nodes {

struct VirtualRigResult {
  std::vector<CycleRecord> records;
  CycleStats stats;
  std::uint64_t frames = 0;
  std::uint64_t faults = 0;
  Fault final_fault = Fault::None;
  canopen::Counters counters;  // the controller node's
  canopen::TimeUs bus_busy_us = 0;  // with a bitrate: time the bus carried frames
};

// Runs until the controller's trajectory time reaches duration_s (after its pre-roll). candump_log,
// if not empty, receives every frame in candump -l format with virtual timestamps from epoch_us.
// bitrate > 0 gives the bus bit timing and CAN arbitration (VirtualBus::setBitrate); 0 is the ideal bus.
VirtualRigResult runVirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, double duration_s,
                               const std::string& candump_log = "", canopen::TimeUs epoch_us = 1700000000000000,
                               std::uint32_t bitrate = 0);

}  // namespace pamc::nodes
