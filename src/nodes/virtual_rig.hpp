// Controller node and emulator nodes on the in-process bus in virtual time: the whole rig, every
// frame through the CANopen layer, deterministic and faster than real time.
#pragma once

#include <functional>
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

// Optional: a live rig (paced to the wall clock) whose frames and records go elsewhere.
struct VirtualRigHooks {
  // Pace the run: 1 ms of bus time per millisecond of wall time (CLOCK_MONOTONIC), as a node on a real
  // bus would run; a late step is caught up at once.
  bool realtime = false;
  // Every frame on the bus with its bus time (e.g. into a logger's ring).
  std::function<void(const canopen::Frame&, canopen::TimeUs)> tap;
  // Each cycle record as the controller produces it; when set, the result keeps no records.
  std::function<void(const CycleRecord&)> on_record;
  // After every step (1 ms of bus time); false stops the run.
  std::function<bool(canopen::TimeUs)> on_step;
};

// Runs until the controller's trajectory time reaches duration_s (after its pre-roll; with realtime,
// 0 runs until on_step says stop). candump_log, if not empty, receives every frame in candump -l format
// with virtual timestamps from epoch_us; it is handed to the kernel (write(2)) at cycle boundaries at
// least once per millisecond of wall time, so a crash loses at most the last millisecond of frames.
// bitrate > 0 gives the bus bit timing and CAN arbitration (VirtualBus::setBitrate); 0 is the ideal bus.
VirtualRigResult runVirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, double duration_s,
                               const std::string& candump_log = "", canopen::TimeUs epoch_us = 1700000000000000,
                               std::uint32_t bitrate = 0, const VirtualRigHooks& hooks = VirtualRigHooks());

}  // namespace pamc::nodes
