#pragma once
// NMT master supervision of a set of slaves (CiA 301 7.2.8, the start-up part of CiA 302-2 without
// configuration): every slave is started after its boot-up; one that comes back after a heartbeat loss
// is re-booted (reset communication), so it boots up and is started afresh; one that stays in
// Pre-operational after a start gets another. The application may hold a slave in Pre-operational for
// reasons of its own (a bit per reason); the slave is started when the last reason is released.
//
// The master takes the node's heartbeat hook and passes what the application must react to on as
// SlaveEvents. All of it runs on the node's thread; nothing is allocated after addSlave().
#include <cstdint>
#include <functional>
#include <vector>

#include "canopen/node.hpp"

namespace pamc::canopen {

enum class SlaveEvent : std::uint8_t {
  Lost,             // its heartbeat timed out
  BootUp,           // it sent a boot-up: it lost its state (the master starts it unless held)
  LeftOperational,  // it reported Pre-operational while not held (the master starts it again)
  Stopped,          // it reported Stopped while not held
};
const char* slaveEventName(SlaveEvent e);

class NmtMaster {
 public:
  using EventHook = std::function<void(std::uint8_t id, SlaveEvent event, TimeUs now)>;
  // A started slave must report Operational within this time (three heartbeats of 100 ms).
  static constexpr TimeUs kStartGraceUs = 300'000;

  struct Counters {
    std::uint64_t starts = 0;   // NMT start sent to a slave
    std::uint64_t reboots = 0;  // NMT reset communication to a slave back after a heartbeat loss
    std::uint64_t holds = 0;    // slave sent to Pre-operational by hold()
  };

  explicit NmtMaster(Node& node);
  NmtMaster(const NmtMaster&) = delete;
  NmtMaster& operator=(const NmtMaster&) = delete;

  // Supervise this node-ID (its heartbeat must be consumed: 0x1016 of the master's dictionary).
  void addSlave(std::uint8_t id);
  void onEvent(EventHook hook) { hook_ = std::move(hook); }

  // NMT start, unless the slave is held.
  void start(std::uint8_t id, TimeUs now) noexcept;
  // Keep the slave in Pre-operational for `reason` (a bit); the first reason sends it there.
  void hold(std::uint8_t id, std::uint8_t reason) noexcept;
  // Drop `reason`; with no reason left the slave is started.
  void release(std::uint8_t id, std::uint8_t reason, TimeUs now) noexcept;
  std::uint8_t holdReasons(std::uint8_t id) const noexcept;

  // The slave cannot run: Stopped, or Pre-operational beyond the grace after a start (then another
  // start is sent).
  bool down(std::uint8_t id, TimeUs now) noexcept;
  // A start went out less than kStartGraceUs ago and no Operational heartbeat followed yet.
  bool starting(std::uint8_t id, TimeUs now) const noexcept;
  bool timedOut(std::uint8_t id) const { return node_.heartbeatConsumer().timedOut(id); }

  const Counters& counters() const noexcept { return counters_; }

 private:
  struct Slave {
    std::uint8_t id = 0;
    bool lost = false;             // heartbeat timed out: re-boot it when it is back
    TimeUs start_sent = kNever;    // NMT start sent, no Operational heartbeat yet
    std::uint8_t hold = 0;         // reasons to keep it in Pre-operational
  };
  Slave* find(std::uint8_t id) noexcept;
  const Slave* find(std::uint8_t id) const noexcept;
  void startSlave(Slave& s, TimeUs now) noexcept;
  void onHeartbeat(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept;
  void emit(std::uint8_t id, SlaveEvent e, TimeUs now) {
    if (hook_) hook_(id, e, now);
  }

  Node& node_;
  std::vector<Slave> slaves_;
  EventHook hook_;
  Counters counters_;
};

}  // namespace pamc::canopen
