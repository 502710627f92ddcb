// NMT (CiA 301, 7.2.8): slave state machine, boot-up message, and master commands.
#pragma once

#include <cstdint>
#include <functional>

#include "canopen/service.hpp"

namespace pamc::canopen {

enum class NmtCommand : std::uint8_t {
  Start = 0x01,
  Stop = 0x02,
  EnterPreOperational = 0x80,
  ResetNode = 0x81,
  ResetCommunication = 0x82,
};

inline constexpr std::uint32_t kNmtCobId = 0x000;
inline constexpr std::uint32_t kHeartbeatCobIdBase = 0x700;  // also the boot-up message

// Master side: the frame "000#<cmd><node>"; node 0 addresses all nodes.
Frame nmtCommandFrame(NmtCommand cmd, std::uint8_t target_node);

class Nmt {
 public:
  // Called on every state change (also Initialising -> Pre-operational after a reset).
  using StateHook = std::function<void(NmtState from, NmtState to, TimeUs now)>;
  // Called for reset node / reset communication; the node restores defaults and calls bootUp().
  using ResetHook = std::function<void(NmtCommand cmd, TimeUs now)>;

  explicit Nmt(NodeContext& ctx) : ctx_(ctx) {}
  void setHooks(StateHook on_state, ResetHook on_reset) {
    on_state_ = std::move(on_state);
    on_reset_ = std::move(on_reset);
  }
  // Subscribes COB-ID 0 (configuration time).
  void subscribe();

  // Initialising -> sends boot-up "700+id#00" -> Pre-operational.
  void bootUp(TimeUs now);
  // Applies a command locally, exactly as if it had been received.
  void apply(NmtCommand cmd, TimeUs now);
  NmtState state() const { return ctx_.state; }
  // Master: sends an NMT command (does not change this node's own state).
  bool sendCommand(NmtCommand cmd, std::uint8_t target_node);

  void onFrame(const Frame& f, TimeUs now);

 private:
  void setState(NmtState s, TimeUs now);
  NodeContext& ctx_;
  StateHook on_state_;
  ResetHook on_reset_;
};

}  // namespace pamc::canopen
