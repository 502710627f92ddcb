// NmtMaster's "boot slave" process (CiA 302-2; the steps are listed in nmt_master.hpp): reset
// communication and the boot-up, identity, reads, the keep-alive check, configuration and its read-back,
// the application's configuration, the first heartbeat; retries of unanswered steps, the boot time, one
// error per failure.
#include <algorithm>
#include <cstdio>

#include "canopen/nmt_master.hpp"
#include "canopen/sdo_abort.hpp"

namespace pamc::canopen {

namespace {
std::string hex32(std::uint32_t v) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%08X", v);
  return b;
}
std::uint32_t le32(const std::uint8_t* d, std::size_t len) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < len && i < 4; ++i) v |= static_cast<std::uint32_t>(d[i]) << (8 * i);
  return v;
}
std::uint64_t le64(const std::uint8_t* d, std::size_t len) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < len && i < 8; ++i) v |= static_cast<std::uint64_t>(d[i]) << (8 * i);
  return v;
}
const char* identityName(std::uint16_t index, std::uint8_t sub) {
  if (index == 0x1000) return "device type";
  switch (sub) {
    case 1: return "vendor-ID";
    case 2: return "product code";
    case 3: return "revision";
    default: return "serial number";
  }
}
}  // namespace

// The step an operation belongs to, as a failure names it.
BootStep NmtMaster::stepOf(OpKind k) noexcept {
  switch (k) {
    case OpKind::Present:
    case OpKind::Expect: return BootStep::Identity;
    case OpKind::Read: return BootStep::Read;
    case OpKind::KeepRtr:
    case OpKind::Write: return BootStep::Configuration;
    case OpKind::Verify: return BootStep::ReadBack;
    case OpKind::Config: return BootStep::Application;
  }
  return BootStep::Configuration;
}

const char* bootStepName(BootStep s) {
  switch (s) {
    case BootStep::Reset: return "reset communication";
    case BootStep::Identity: return "identity check";
    case BootStep::Read: return "read";
    case BootStep::Configuration: return "configuration";
    case BootStep::ReadBack: return "read-back";
    case BootStep::Application: return "application configuration";
    case BootStep::Heartbeat: return "first heartbeat";
    case BootStep::BootTime: return "boot time";
  }
  return "?";
}

// At the master's start (the reset of those not kept alive went out with reset_sent). Kept alive: its
// identity first, then its state decides (checkNode), as Lely's master has it.
void NmtMaster::beginBoot(Slave& s, TimeUs now, bool reset_sent) noexcept {
  s.error = BootError{};
  s.tries_left = retriesOf(s.boot.assignment);
  s.identified = false;
  if ((s.boot.assignment & kAssignKeepAlive) != 0) return steps(s, 0, true);
  reset(s, now, !reset_sent);
}

void NmtMaster::reset(Slave& s, TimeUs now, bool send) noexcept {
  if (send) node_.sendNmt(NmtCommand::ResetCommunication, s.id);
  ++counters_.resets;
  s.state = Boot::Resetting;
  s.deadline = now + kBootUpTimeoutUs;
  s.start.sent = kNever;
  s.start.due = false;
  arm();
}

void NmtMaster::steps(Slave& s, std::size_t from, bool checking) noexcept {
  s.checking = checking;
  s.kept = false;
  s.start.due = false;
  s.next_op = from;
  s.end_op = checking ? s.config_op : s.ops.size();
  s.tries_left = retriesOf(s.boot.assignment);
  s.deadline = kNever;
  // Decided here, not in poll() - which the SYNC callback runs and which must not format a failure.
  if (!checking && !s.plan_error.empty()) return bootFailed(s, BootStep::Configuration, 0, s.plan_error);
  if (s.next_op >= s.end_op) return checking ? checkNode(s, node_.now()) : awaitHeartbeat(s, node_.now());
  s.state = Boot::Waiting;
  poll(node_.now());
}

// Kept alive, its identity checked (CiA 302-2 "check node state"): Operational, it is left as it is;
// otherwise a consumer time for a heartbeat to tell, then reset communication.
void NmtMaster::checkNode(Slave& s, TimeUs now) noexcept {
  const auto& hb = node_.heartbeatConsumer();
  if (running(s)) return keptRunning(s, now);
  if (hb.timeoutUs(s.id) == 0 || hb.timedOut(s.id)) return resetAfterCheck(s, now);
  s.state = Boot::Checking;
  s.deadline = now + hb.timeoutUs(s.id);
  arm();
  poll(now);  // the next slave waiting for the SDO client
}

void NmtMaster::keptRunning(Slave& s, TimeUs now) noexcept {
  s.kept = true;
  done(s, now);
}

// Not running: reset as any other; its identity was checked, so its boot-up goes on at the configuration.
void NmtMaster::resetAfterCheck(Slave& s, TimeUs now) noexcept {
  reset(s, now);
  s.identified = true;
  poll(now);
}

void NmtMaster::runBoot(Slave& s) noexcept {
  if (s.next_op >= s.end_op) return s.checking ? checkNode(s, node_.now()) : awaitHeartbeat(s, node_.now());
  const Op& op = s.ops[s.next_op];
  const std::uint8_t id = s.id;
  auto reply = [this, id](std::uint32_t code, const std::uint8_t* d, std::size_t len) {
    if (Slave* sl = find(id)) onBootReply(*sl, code, d, len);
  };
  auto& sdo = node_.sdoClient();
  bool sent;
  if (op.kind == OpKind::Write) {
    const auto& w = s.boot.writes[op.item];
    sent = sdo.download(id, op.index, op.sub, w.data.data(), w.data.size(), reply);
  } else if (op.kind == OpKind::Config) {
    const auto& c = s.boot.config[op.item];
    const std::uint32_t v = c.value ? c.value() : 0u;
    const std::uint8_t b[4] = {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
                               static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
    sent = sdo.download(id, op.index, op.sub, b, std::clamp<std::size_t>(c.size, 1, 4), reply);
  } else {
    sent = sdo.upload(id, op.index, op.sub, reply);
  }
  if (!sent) s.state = Boot::Waiting;  // the client is busy: poll() goes on from this operation
}

void NmtMaster::onBootReply(Slave& s, std::uint32_t code, const std::uint8_t* data, std::size_t len) noexcept {
  if (s.state != Boot::Running || s.next_op >= s.ops.size()) return;
  const Op& op = s.ops[s.next_op];
  const BootStep step = stepOf(op.kind);
  if (code == kAbortTimeout && s.tries_left > 0) {
    // No answer (still booting, a frame lost): the same step again.
    --s.tries_left;
    ++counters_.boot_retries;
    return runBoot(s);
  }
  if (code != kSdoOk) {
    const bool write = op.kind == OpKind::Write || op.kind == OpKind::Config;
    const char* what = write ? " write refused: " : " read failed: ";
    return bootFailed(s, step, code, entryName(op.index, op.sub) + what + sdoAbortText(code));
  }
  if (!checkReply(s, op, data, len)) return;
  ++s.next_op;
  s.tries_left = retriesOf(s.boot.assignment);
  runBoot(s);
}

// The value an identity check, a read or a read-back got; false (the boot failed) if it is not right.
bool NmtMaster::checkReply(Slave& s, const Op& op, const std::uint8_t* data, std::size_t len) noexcept {
  const std::string at = entryName(op.index, op.sub);
  switch (op.kind) {
    case OpKind::Present: return true;
    case OpKind::KeepRtr: keepRtr(s, op, le32(data, len)); return true;
    case OpKind::Expect: {
      const std::uint32_t v = le32(data, len);
      if (v == op.expected) return true;
      bootFailed(s, BootStep::Identity, 0,
                 at + " " + identityName(op.index, op.sub) + " is " + hex32(v) + ", expected " + hex32(op.expected));
      return false;
    }
    case OpKind::Read: {
      std::string why;
      const auto& r = s.boot.reads[op.item];
      if (!r.on_value || r.on_value(data, len, &why)) return true;
      bootFailed(s, BootStep::Read, 0, at + ": " + why);
      return false;
    }
    case OpKind::Write:
    case OpKind::Config: return true;
    case OpKind::Verify: {
      const auto& w = s.boot.writes[op.item];
      if (len == w.data.size() && std::equal(w.data.begin(), w.data.end(), data)) return true;
      char b[96];
      std::snprintf(b, sizeof b, " reads back 0x%llX, written 0x%llX", static_cast<unsigned long long>(le64(data, len)),
                    static_cast<unsigned long long>(le64(w.data.data(), w.data.size())));
      bootFailed(s, BootStep::ReadBack, 0, at + b);
      return false;
    }
  }
  return true;
}

// The device's bit 30 of a PDO COB-ID (a TPDO's "no RTR", reserved in an RPDO's) into every write of the
// entry - the disable, the enable - and so into its read-back; bit 31 stays as the configuration has it.
void NmtMaster::keepRtr(Slave& s, const Op& op, std::uint32_t device_cob) noexcept {
  const std::uint8_t bit = static_cast<std::uint8_t>(kPdoNoRtrBit >> 24);
  for (auto& w : s.boot.writes) {
    if (w.index != op.index || w.sub != op.sub || w.data.size() != 4) continue;
    w.data[3] = static_cast<std::uint8_t>((device_cob & kPdoNoRtrBit) != 0 ? w.data[3] | bit : w.data[3] & ~bit);
  }
}

// Configured: where 0x1016 supervises the slave, its first heartbeat must come before it is started.
void NmtMaster::awaitHeartbeat(Slave& s, TimeUs now) noexcept {
  const auto& hb = node_.heartbeatConsumer();
  if (hb.timeoutUs(s.id) == 0 || hb.alive(s.id)) return done(s, now);
  s.state = Boot::Heartbeat;
  s.tries_left = retriesOf(s.boot.assignment);
  s.deadline = now + hb.timeoutUs(s.id);
  arm();
  poll(now);  // the next slave waiting for the SDO client
}

void NmtMaster::done(Slave& s, TimeUs now) noexcept {
  s.state = Boot::Done;
  s.deadline = kNever;
  s.start.due = true;
  if (s.kept)
    ++counters_.kept_alive;
  else
    ++counters_.boots;
  emit(s.id, s.kept ? SlaveEvent::KeptAlive : SlaveEvent::Configured, now);
  startReady(now);
  poll(now);  // the next slave waiting for its boot
}

void NmtMaster::bootFailed(Slave& s, BootStep step, std::uint32_t code, std::string text) noexcept {
  s.state = Boot::Failed;
  s.deadline = kNever;
  s.error = BootError{step, code, std::move(text)};
  ++counters_.boot_failures;
  // Left stopped: nothing of it moves on the bus until it boots again.
  node_.sendNmt(NmtCommand::Stop, s.id);
  s.start.sent = kNever;
  s.start.due = false;
  const TimeUs now = node_.now();
  emit(s.id, SlaveEvent::BootFailed, now);
  poll(now);
}

// What the heartbeat protocol tells a slave's boot: a boot-up starts the SDO steps (after a reset, or a
// slave that booted by itself); a heartbeat ends the keep-alive check or the wait for the first one.
void NmtMaster::onBootEvent(Slave& s, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept {
  if (!begun_ || (startup_ & kStartupMaster) == 0) return;
  if (ev == HeartbeatEvent::BootUp) {
    s.error = BootError{};
    const std::size_t from = s.identified ? s.config_op : 0;  // reset by the keep-alive check
    s.identified = false;
    return steps(s, from, false);
  }
  if (s.state == Boot::Checking) return st == NmtState::Operational ? keptRunning(s, now) : resetAfterCheck(s, now);
  if (s.state == Boot::Heartbeat) done(s, now);
}

// The steps the slave has not answered in time, and the boot time.
void NmtMaster::onTimer(TimeUs now) noexcept {
  for (auto& s : slaves_) {
    if (s.deadline == kNever || now < s.deadline) continue;
    s.deadline = kNever;
    const bool again = s.tries_left > 0;
    if (again && s.state != Boot::Checking) --s.tries_left, ++counters_.boot_retries;
    if (s.state == Boot::Checking) {
      resetAfterCheck(s, now);  // no heartbeat within its consumer time: not running
    } else if (s.state == Boot::Resetting) {
      if (again)
        reset(s, now);
      else
        bootFailed(s, BootStep::Reset, 0,
                   "no boot-up within " + std::to_string(kBootUpTimeoutUs / 1000) + " ms of NMT reset communication");
    } else if (s.state == Boot::Heartbeat) {
      const TimeUs t = node_.heartbeatConsumer().timeoutUs(s.id);
      if (again)
        s.deadline = now + t;
      else
        bootFailed(
            s, BootStep::Heartbeat, 0,
            "no heartbeat within " + std::to_string(t / 1000) + " ms (its consumer time, 0x1016) of its configuration");
    }
  }
  if (boot_deadline_ != kNever && now >= boot_deadline_) {
    boot_deadline_ = kNever;
    for (auto& s : slaves_)
      if (bootable(s) && (s.boot.assignment & kAssignMandatory) != 0 && s.state != Boot::Done &&
          s.state != Boot::Failed)
        bootFailed(s, BootStep::BootTime, 0,
                   "not booted within the boot time 0x1F89 of " + std::to_string(boot_time_ms_) + " ms");
  }
  arm();
}

void NmtMaster::arm() noexcept {
  TimeUs next = boot_deadline_;
  for (const auto& s : slaves_) next = std::min(next, s.deadline);
  node_.setTimer(next);
}

}  // namespace pamc::canopen
