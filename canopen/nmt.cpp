#include "canopen/nmt.hpp"

namespace pamc::canopen {

const char* nmtStateName(NmtState s) {
  switch (s) {
    case NmtState::Initialising: return "initialising";
    case NmtState::Stopped: return "stopped";
    case NmtState::Operational: return "operational";
    case NmtState::PreOperational: return "pre-operational";
  }
  return "unknown";
}

Frame nmtCommandFrame(NmtCommand cmd, std::uint8_t target_node) {
  Frame f;
  f.id = kNmtCobId;
  f.len = 2;
  f.data[0] = static_cast<std::uint8_t>(cmd);
  f.data[1] = target_node;
  return f;
}

void Nmt::subscribe() { ctx_.dispatcher.subscribe<&Nmt::onFrame>(kNmtCobId, this); }

void Nmt::bootUp(TimeUs now) {
  ctx_.state = NmtState::Initialising;
  Frame f;
  f.id = kHeartbeatCobIdBase + ctx_.node_id;
  f.len = 1;
  f.data[0] = 0;
  ctx_.send(f);
  setState(NmtState::PreOperational, now);
}

void Nmt::setState(NmtState s, TimeUs now) {
  NmtState old = ctx_.state;
  ctx_.state = s;
  if (old != s && on_state_) on_state_(old, s, now);
}

void Nmt::apply(NmtCommand cmd, TimeUs now) {
  if (ctx_.state == NmtState::Initialising) return;  // not booted yet: nothing to switch
  switch (cmd) {
    case NmtCommand::Start: setState(NmtState::Operational, now); break;
    case NmtCommand::Stop: setState(NmtState::Stopped, now); break;
    case NmtCommand::EnterPreOperational: setState(NmtState::PreOperational, now); break;
    case NmtCommand::ResetNode:
    case NmtCommand::ResetCommunication:
      setState(NmtState::Initialising, now);
      if (on_reset_) on_reset_(cmd, now);
      break;
  }
}

bool Nmt::sendCommand(NmtCommand cmd, std::uint8_t target_node) { return ctx_.send(nmtCommandFrame(cmd, target_node)); }

void Nmt::onFrame(const Frame& f, TimeUs now) {
  if (f.len != 2) {
    ++ctx_.counters.wrong_length;
    return;
  }
  std::uint8_t target = f.data[1];
  if (target != 0 && target != ctx_.node_id) return;
  switch (f.data[0]) {
    case 0x01:
    case 0x02:
    case 0x80:
    case 0x81:
    case 0x82: apply(static_cast<NmtCommand>(f.data[0]), now); break;
    default: ++ctx_.counters.nmt_invalid_command; break;
  }
}

}  // namespace pamc::canopen
