// Heartbeat (CiA 301, 7.2.8.3.2.2): producer (period 0x1017) and consumer (0x1016) with timeout events.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include "canopen/service.hpp"

namespace pamc::canopen {

class HeartbeatProducer {
 public:
  explicit HeartbeatProducer(NodeContext& ctx) : ctx_(ctx) {}
  // Reconfigures when an SDO writes 0x1017 (configuration time).
  void registerHooks();
  // Reads 0x1017 and schedules the next heartbeat one period after now.
  void configure(TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const { return next_us_; }
  TimeUs periodUs() const { return period_us_; }

 private:
  NodeContext& ctx_;
  TimeUs period_us_ = 0;
  TimeUs next_us_ = kNever;
};

enum class HeartbeatEvent : std::uint8_t {
  Started,       // first heartbeat after configuration, boot-up or a timeout: monitoring runs
  Timeout,       // no heartbeat within the consumer time
  BootUp,        // the remote node sent its boot-up message (it was reset)
  StateChanged,  // the NMT state in the heartbeat changed
};
const char* heartbeatEventName(HeartbeatEvent e);

class HeartbeatConsumer {
 public:
  using EventHook = std::function<void(std::uint8_t node_id, HeartbeatEvent event, NmtState remote, TimeUs now)>;

  explicit HeartbeatConsumer(NodeContext& ctx) : ctx_(ctx) {}
  void setHook(EventHook hook) { hook_ = std::move(hook); }
  // Sizes the monitor table from 0x1016 and installs the SDO validator/observer (configuration time).
  void registerHooks();
  // Reads 0x1016 and (re)subscribes to 0x700+node of every monitored node; monitoring restarts.
  void configure();
  void onFrame(const Frame& f, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;

  // Also report this node's boot-up and state when 0x1016 gives it no consumer time (never a timeout):
  // an NMT master hears the boot-up of every slave it resets (configuration time).
  void watch(std::uint8_t node_id);

  // State last reported by a monitored or watched node (Initialising if unknown or neither).
  NmtState remoteState(std::uint8_t node_id) const;
  bool timedOut(std::uint8_t node_id) const;
  // A heartbeat came since the node's last boot-up (or since monitoring began) and has not timed out.
  bool alive(std::uint8_t node_id) const;
  // Its consumer heartbeat time from 0x1016 (0: not supervised).
  TimeUs timeoutUs(std::uint8_t node_id) const;
  std::size_t monitoredCount() const;

 private:
  enum class Status : std::uint8_t { Unused, Waiting, Active, TimedOut };
  struct Slot {
    std::uint8_t node_id = 0;
    TimeUs timeout_us = 0;  // 0: watched only
    TimeUs last_us = 0;
    NmtState state = NmtState::Initialising;
    Status status = Status::Unused;
  };
  void emit(const Slot& s, HeartbeatEvent e, TimeUs now) {
    if (hook_) hook_(s.node_id, e, s.state, now);
  }
  const Slot* slotFor(std::uint8_t node_id) const;
  Slot* slotFor(std::uint8_t node_id) {
    return const_cast<Slot*>(static_cast<const HeartbeatConsumer*>(this)->slotFor(node_id));
  }

  NodeContext& ctx_;
  EventHook hook_;
  std::vector<Slot> slots_;  // one per 0x1016 sub-index, then one per watched node; sized at configuration
  std::array<std::uint16_t, 128> slot_of_{};  // node-ID -> its slot + 1 (0: not consumed), set by configure()
  // The earliest timeout, kept until a slot changes: advance() in every cycle looks at it, not at every
  // slot (a master's 0x1016 has room for many slaves).
  mutable TimeUs next_ = kNever;
  mutable bool stale_ = true;
  std::size_t consumer_slots_ = 0;
  std::vector<std::uint8_t> watched_;
};

}  // namespace pamc::canopen
