#include "canopen/nmt_master.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace pamc::canopen {

const char* slaveEventName(SlaveEvent e) {
  switch (e) {
    case SlaveEvent::Lost: return "lost";
    case SlaveEvent::BootUp: return "boot-up";
    case SlaveEvent::LeftOperational: return "left operational";
    case SlaveEvent::Stopped: return "stopped";
  }
  return "?";
}

NmtMaster::NmtMaster(Node& node) : node_(node) {
  node_.onHeartbeat([this](std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) { onHeartbeat(id, ev, st, now); });
}

void NmtMaster::addSlave(std::uint8_t id) {
  if (id < 1 || id > 127) throw std::invalid_argument("NMT master: slave node-ID " + std::to_string(id) + " is not 1..127");
  if (id == node_.nodeId()) throw std::invalid_argument("NMT master: slave node-ID " + std::to_string(id) + " is the master's own");
  if (find(id) != nullptr) return;
  slaves_.push_back(Slave{id});
}

NmtMaster::Slave* NmtMaster::find(std::uint8_t id) noexcept {
  auto it = std::find_if(slaves_.begin(), slaves_.end(), [id](const Slave& s) { return s.id == id; });
  return it == slaves_.end() ? nullptr : &*it;
}
const NmtMaster::Slave* NmtMaster::find(std::uint8_t id) const noexcept {
  return const_cast<NmtMaster*>(this)->find(id);
}

void NmtMaster::startSlave(Slave& s, TimeUs now) noexcept {
  node_.sendNmt(NmtCommand::Start, s.id);
  s.start_sent = now;
  ++counters_.starts;
}

void NmtMaster::start(std::uint8_t id, TimeUs now) noexcept {
  if (Slave* s = find(id); s != nullptr && s->hold == 0) startSlave(*s, now);
}

void NmtMaster::hold(std::uint8_t id, std::uint8_t reason) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return;
  const bool was = s->hold != 0;
  s->hold |= reason;
  if (was) return;
  node_.sendNmt(NmtCommand::EnterPreOperational, id);
  s->start_sent = kNever;
  ++counters_.holds;
}

void NmtMaster::release(std::uint8_t id, std::uint8_t reason, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr || (s->hold & reason) == 0) return;
  s->hold = static_cast<std::uint8_t>(s->hold & ~reason);
  if (s->hold == 0) startSlave(*s, now);
}

std::uint8_t NmtMaster::holdReasons(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s ? s->hold : 0;
}

bool NmtMaster::down(std::uint8_t id, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return false;
  const NmtState st = node_.heartbeatConsumer().remoteState(id);
  if (st == NmtState::Stopped) return true;
  if (st != NmtState::PreOperational) return false;
  if (starting(id, now)) return false;
  startSlave(*s, now);  // it did not follow the last start: send another
  return true;
}

bool NmtMaster::starting(std::uint8_t id, TimeUs now) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && s->start_sent != kNever && now - s->start_sent < kStartGraceUs;
}

void NmtMaster::onHeartbeat(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return;
  const bool held = s->hold != 0;
  switch (ev) {
    case HeartbeatEvent::Timeout:
      s->lost = true;
      s->start_sent = kNever;
      emit(id, SlaveEvent::Lost, now);
      break;
    case HeartbeatEvent::BootUp:
      // A slave that rebooted lost its state and waits in Pre-operational: start it again.
      s->lost = false;
      emit(id, SlaveEvent::BootUp, now);
      if (!held) startSlave(*s, now);
      break;
    case HeartbeatEvent::Started:
      if (s->lost) {
        // Back after a timeout without a boot-up: re-boot it (reset communication); its boot-up starts it.
        s->lost = false;
        node_.sendNmt(NmtCommand::ResetCommunication, id);
        ++counters_.reboots;
      } else if (st == NmtState::Operational) {
        s->start_sent = kNever;
      } else if (st == NmtState::PreOperational && !held) {
        startSlave(*s, now);
      }
      break;
    case HeartbeatEvent::StateChanged:
      if (st == NmtState::Operational) {
        s->start_sent = kNever;
      } else if (st == NmtState::PreOperational && !held) {
        emit(id, SlaveEvent::LeftOperational, now);
        startSlave(*s, now);
      } else if (st == NmtState::Stopped && !held) {
        emit(id, SlaveEvent::Stopped, now);
      }
      break;
  }
}

}  // namespace pamc::canopen
