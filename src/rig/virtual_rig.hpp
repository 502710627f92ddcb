// Controller node and emulator nodes on the in-process bus in virtual time: the whole rig, every
// frame through the CANopen layer, deterministic and faster than real time.
#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"
#include "nodes/fault_report.hpp"

namespace pamc::rig {

// The rig declared once and then stepped (the shape of a simulation diagram: declare, then step).
// The constructor builds the bus (with bit timing when bitrate > 0), the controller node and the
// emulator nodes, and connects them; start() boots them; step() advances the bus by one period and
// hands the controller's cycle records to the sink (or keeps them) and the controller's fault lines to
// its configuration's log. Tools that need their own station
// on the bus (an SDO client, an NMT master, a fault injector) take a port with addPort() before start().
class VirtualRig {
 public:
  // Injection on the emulator's side of the bus: every frame the emulator nodes send passes through
  // this first and may be changed (return true) or dropped (return false).
  using FrameEdit = std::function<bool(canopen::Frame&)>;

  VirtualRig(const nodes::ControllerNodeConfig& c, const nodes::EmulatorConfig& e, std::uint32_t bitrate = 0,
             FrameEdit emulator_tx = nullptr);
  VirtualRig(const VirtualRig&) = delete;
  VirtualRig& operator=(const VirtualRig&) = delete;

  canopen::VirtualBus::Port& addPort() { return bus_.addPort(); }
  void addTap(canopen::VirtualBus::Tap tap) { bus_.addTap(std::move(tap)); }
  // Where the cycle records go; without a sink they are kept (records()).
  void setRecordSink(std::function<void(const nodes::CycleRecord&)> sink) { sink_ = std::move(sink); }

  void start();                             // boot-up of the emulator nodes, then the controller
  void startEmulator();                     // the two halves of start(): slaves first, e.g. to
  void startController();                   // change them over SDO before the controller comes
  void step(canopen::TimeUs dt_us = 1000);  // advance the bus, collect the records
  void runFor(double seconds) {             // steps of 1 ms
    for (long k = 0, n = static_cast<long>(seconds * 1000.0 + 0.5); k < n; ++k) step();
  }

  canopen::VirtualBus& bus() { return bus_; }
  canopen::TimeUs now() const { return bus_.now(); }
  nodes::ControllerNode& controller() { return *ctrl_; }
  nodes::EmulatorNodes& emulator() { return *emu_; }
  std::vector<nodes::CycleRecord>& records() { return records_; }

 private:
  canopen::VirtualBus bus_;  // first: outlives the nodes that send through it
  canopen::VirtualBus::Port& cport_;
  canopen::VirtualBus::Port& eport_;
  // The emulator's transport: the port itself, or the port behind the frame edit.
  class EditingTransport final : public canopen::Transport {
   public:
    EditingTransport(canopen::Transport& inner, FrameEdit edit) : inner_(inner), edit_(std::move(edit)) {}
    bool send(const canopen::Frame& f) override { return sendUntil(f, canopen::kNever); }
    bool sendUntil(const canopen::Frame& f, canopen::TimeUs deadline) override {
      canopen::Frame g = f;
      if (edit_ && !edit_(g)) return true;  // dropped on the way, as a lost frame is
      return inner_.sendUntil(g, deadline);
    }
    std::size_t queued() const override { return inner_.queued(); }
    std::uint64_t expiredCount() const override { return inner_.expiredCount(); }

   private:
    canopen::Transport& inner_;
    FrameEdit edit_;
  };
  EditingTransport etx_;
  std::unique_ptr<nodes::ControllerNode> ctrl_;  // rings: heap
  std::unique_ptr<nodes::EmulatorNodes> emu_;
  std::function<void(const nodes::CycleRecord&)> sink_;
  std::vector<nodes::CycleRecord> records_;
  nodes::FaultReporter reporter_;
};

struct VirtualRigResult {
  std::vector<nodes::CycleRecord> records;
  nodes::CycleStats stats;
  std::uint64_t frames = 0;
  std::uint64_t faults = 0;
  nodes::Fault final_fault = nodes::Fault::None;
  canopen::Counters counters;       // the controller node's
  canopen::TimeUs bus_busy_us = 0;  // with a bitrate: time the bus carried frames
  // Paced in real time: how late each wake-up came, and how many came a whole period late or more.
  nodes::Histogram wake_late_us;
  std::uint64_t wake_overruns = 0;
  std::string failure;  // why the run failed (runFailure), empty if it did not
};

// Optional: a live rig (paced to the wall clock) whose frames and records go elsewhere.
struct VirtualRigHooks {
  // Pace the run: 1 ms of bus time per millisecond of wall time (CLOCK_MONOTONIC), as a node on a real
  // bus would run; a late step is caught up at once.
  bool realtime = false;
  // With duration 0: run until on_step says stop (also in virtual time).
  bool until_stopped = false;
  // Every frame on the bus with its bus time (e.g. into a logger's ring).
  std::function<void(const canopen::Frame&, canopen::TimeUs)> tap;
  // Each cycle record as the controller produces it; when set, the result keeps no records.
  std::function<void(const nodes::CycleRecord&)> on_record;
  // After every step (1 ms of bus time); false stops the run.
  std::function<bool(canopen::TimeUs)> on_step;
};

// Runs until the controller's trajectory time reaches duration_s (after its pre-roll), in bus time at
// most pre-roll + duration + RunEnd::kStartGraceS (RunEnd; with realtime or until_stopped, 0
// runs until on_step says stop). candump_log, if not empty, receives every frame in candump -l format
// with virtual timestamps from epoch_us; it is handed to the kernel (write(2)) at cycle boundaries at
// least once per millisecond of wall time, so a crash loses at most the last millisecond of frames.
// bitrate > 0 gives the bus bit timing and CAN arbitration (VirtualBus::setBitrate); 0 is the ideal bus.
VirtualRigResult runVirtualRig(const nodes::ControllerNodeConfig& c, const nodes::EmulatorConfig& e, double duration_s,
                               const std::string& candump_log = "", canopen::TimeUs epoch_us = 1700000000000000,
                               std::uint32_t bitrate = 0, const VirtualRigHooks& hooks = VirtualRigHooks());

}  // namespace pamc::rig
