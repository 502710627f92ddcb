// The controller node's faults (faults.hpp, the one table): causes raised by the drivers, the node's
// hooks and the bus checks; each cause's EMCY once per episode; the safe state from the first safety
// cause until the causes have been gone for recover_cycles; warnings that clear themselves; the EMCY
// resets. Runs in the cycle: nothing allocated, nothing thrown.
#pragma once

#include <atomic>
#include <cstdint>

#include "canopen/node.hpp"
#include "nodes/faults.hpp"

namespace pamc::nodes {

class FaultSupervisor {
 public:
  struct Counters {
    std::uint64_t episodes = 0;  // entries into the safe state
    std::uint64_t recoveries = 0;
    std::uint64_t safe_cycles = 0;  // cycles that sent the safe value
    std::uint64_t warnings = 0;     // warning EMCYs sent
  };

  // channel: the channel it supervises, named in byte 3 of its EMCYs (1..8; 0: the node's only one).
  // reports_bus: it sends the EMCYs of the bus's causes (SYNC, CAN errors, collisions, wrong lengths),
  // which every channel meets at once: one channel of a node reports them, the others only react.
  FaultSupervisor(canopen::Node& node, int recover_cycles, std::uint8_t channel = 0, bool reports_bus = true)
      : node_(node),
        recover_cycles_(recover_cycles),
        own_clear_cycles_(recover_cycles),
        channel_(channel),
        reports_bus_(reports_bus) {}

  // The cycles a fault's causes must be gone (the node's recovery time over its SYNC period).
  void setRecoverCycles(int n) noexcept {
    if (own_clear_cycles_ >= recover_cycles_) own_clear_cycles_ = n;
    recover_cycles_ = n;
  }
  void raise(Fault f, std::uint8_t detail = 0) noexcept;
  // Sends the EMCY of every cause not yet reported in this episode; true when a safety cause has just
  // begun an episode (the caller puts the valve at its safe value).
  bool takeCauses(canopen::TimeUs now) noexcept;
  // One cycle in the safe state; true once the causes have been gone for recover_cycles.
  bool safeCycle() noexcept {
    ++counters_.safe_cycles;
    ++own_clear_cycles_;
    return ++clear_cycles_ >= recover_cycles_;
  }
  // In the safe state by a cause of its own (not Fault::OtherChannel) raised within the last
  // recover_cycles: the channel's fault spreads to its partner. Two partners that fault together
  // thus stop spreading once their own causes are gone, and both recover.
  bool spreads() const noexcept { return fault_ != Fault::None && own_clear_cycles_ < recover_cycles_; }
  // Back in control: the EMCY resets of the episode's safety causes.
  void recover() noexcept;
  // Warnings (wrong-length PDO or SYNC) clear themselves after recover_cycles without a new one.
  void clearWarnings() noexcept;
  // Frames this node could not send, frames with a wrong length, bus off: every cycle.
  void pollBus() noexcept;
  void onErrorFrame(const canopen::Frame& f) noexcept;
  // The fault for other threads (fault()), once per cycle.
  void publish() noexcept { pub_.store(fault_, std::memory_order_relaxed); }

  Fault fault() const noexcept { return fault_; }
  Fault published() const noexcept { return pub_.load(std::memory_order_relaxed); }
  std::uint32_t episode() const noexcept { return episode_; }
  std::uint64_t raised() const noexcept { return raised_; }
  canopen::TimeUs reactedAt() const noexcept { return reacted_at_us_; }
  const Counters& counters() const noexcept { return counters_; }

 private:
  bool reports(Fault f) const noexcept;
  const std::uint8_t* resetBytes() noexcept;
  std::uint8_t reset_bytes_[5] = {};

  canopen::Node& node_;
  int recover_cycles_;
  int own_clear_cycles_;  // cycles in the safe state since a cause of its own (recover_cycles: none yet)
  std::uint8_t channel_;
  bool reports_bus_;
  Fault fault_ = Fault::None;
  std::uint32_t pending_ = 0;  // causes raised since the last cycle (bit per Fault)
  std::uint32_t episode_ = 0;  // causes whose EMCY went out in this episode
  std::uint8_t detail_[kFaultCount] = {};
  int clear_cycles_ = 0;
  int warn_clear_ = 0;
  std::uint64_t raised_ = 0;  // episodes begun (faultsRaised)
  canopen::TimeUs reacted_at_us_ = canopen::kNever;
  // What pollBus() saw of the node's counters last time, and whether the controller is bus off.
  struct BusSeen {
    bool off = false;
    std::uint64_t tx_dropped = 0, tx_expired = 0, pdo_length = 0, sync_length = 0;
  } bus_;
  Counters counters_;
  std::atomic<Fault> pub_{Fault::None};
};

}  // namespace pamc::nodes
