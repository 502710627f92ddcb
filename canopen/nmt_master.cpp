// NmtMaster: the slaves, their boot plans from the dictionary, NMT start and hold, and what their
// heartbeats say. The boot process itself is in nmt_boot.cpp.
#include "canopen/nmt_master.hpp"

#include <algorithm>
#include <iterator>
#include <stdexcept>
#include <string>

#include "canopen/sdo_abort.hpp"

namespace pamc::canopen {

const char* slaveEventName(SlaveEvent e) {
  switch (e) {
    case SlaveEvent::Lost: return "lost";
    case SlaveEvent::BootUp: return "boot-up";
    case SlaveEvent::LeftOperational: return "left operational";
    case SlaveEvent::Stopped: return "stopped";
    case SlaveEvent::Configured: return "configured";
    case SlaveEvent::KeptAlive: return "kept alive";
    case SlaveEvent::BootFailed: return "boot failed";
  }
  return "?";
}

namespace {
// The identity entries of the master (0x1F84 + k) and of the slave they are checked against.
struct IdentityEntry {
  std::optional<std::uint32_t> SlaveBoot::*field;
  std::uint16_t index;
  std::uint8_t sub;
};
constexpr std::uint16_t kDeviceTypeIndex = 0x1000;
constexpr IdentityEntry kIdentity[] = {{&SlaveBoot::device_type, kDeviceTypeIndex, 0},
                                       {&SlaveBoot::vendor_id, 0x1018, 1},
                                       {&SlaveBoot::product_code, 0x1018, 2},
                                       {&SlaveBoot::revision, 0x1018, 3},
                                       {&SlaveBoot::serial, 0x1018, 4}};
constexpr std::uint16_t kConsumerHeartbeat = 0x1016, kProducerHeartbeat = 0x1017;
}  // namespace

bool bootFromDictionary(const ObjectDictionary& od, std::uint8_t id, SlaveBoot& out, std::string* why) {
  out = SlaveBoot{};
  if (const Entry* a = od.find(kObjAssignment, id)) out.assignment = static_cast<std::uint32_t>(a->asUnsigned());
  for (std::size_t k = 0; k < std::size(kIdentity); ++k) {
    const Entry* e = od.find(static_cast<std::uint16_t>(kObjDeviceType + k), id);
    if (e != nullptr && e->asUnsigned() != 0) out.*kIdentity[k].field = static_cast<std::uint32_t>(e->asUnsigned());
  }
  const Entry* dcf = od.find(kObjConciseDcf, id);
  if (dcf == nullptr || dcf->size() == 0) return true;
  std::string problem;
  if (decodeConciseDcf(dcf->data(), dcf->size(), out.writes, &problem)) return true;
  if (why) *why = entryName(kObjConciseDcf, id) + " is not a concise DCF: " + problem;
  return false;
}

void bootToDictionary(ObjectDictionary& od, std::uint8_t id, const SlaveBoot& boot) {
  od.entry(kObjAssignment, id).set<std::uint32_t>(boot.assignment);
  for (std::size_t k = 0; k < std::size(kIdentity); ++k)
    od.entry(static_cast<std::uint16_t>(kObjDeviceType + k), id)
        .set<std::uint32_t>((boot.*kIdentity[k].field).value_or(0));
  const auto bytes = encodeConciseDcf(boot.writes);
  Entry& dcf = od.entry(kObjConciseDcf, id);
  if (!dcf.write(bytes.data(), bytes.size()))
    throw OdError(entryName(kObjConciseDcf, id) + ": a concise DCF of " + std::to_string(bytes.size()) +
                  " bytes does not fit");
}

std::string checkMasterEntry(const DcfEntry& e) {
  if (e.index != kObjConciseDcf || e.sub == 0 || e.data.empty()) return "";
  ConciseDcf dcf;
  std::string why;
  return decodeConciseDcf(e.data.data(), e.data.size(), dcf, &why)
             ? ""
             : entryName(e.index, e.sub) + " is not a concise DCF: " + why;
}

NmtMaster::NmtMaster(Node& node) : node_(node) {
  node_.onHeartbeat(
      [this](std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) { onHeartbeat(id, ev, st, now); });
  node_.onTimer([this](TimeUs now) { onTimer(now); });
  // A concise DCF written over SDO must decode: the next boot runs it.
  if (node_.od().hasObject(kObjConciseDcf))
    node_.od().addValidator(kObjConciseDcf, [](const Entry& e, const std::uint8_t* d, std::size_t len) {
      ConciseDcf dcf;
      return e.subIndex() == 0 || len == 0 || decodeConciseDcf(d, len, dcf, nullptr) ? kSdoOk : kAbortValueRange;
    });
}

void NmtMaster::addSlave(std::uint8_t id) {
  if (id < 1 || id > 127)
    throw std::invalid_argument("NMT master: slave node-ID " + std::to_string(id) + " is not 1..127");
  if (id == node_.nodeId())
    throw std::invalid_argument("NMT master: slave node-ID " + std::to_string(id) + " is the master's own");
  if (find(id) != nullptr) return;
  slaves_.push_back(Slave{});
  slaves_.back().id = id;
  slave_of_[id] = static_cast<std::uint8_t>(slaves_.size());
  node_.heartbeatConsumer().watch(id);  // its boot-up is heard also where 0x1016 does not supervise it
}

void NmtMaster::setBoot(std::uint8_t id, SlaveBoot boot) {
  Slave* s = find(id);
  if (s == nullptr) throw std::invalid_argument("NMT master: node " + std::to_string(id) + " is not a slave");
  bootToDictionary(node_.od(), id, boot);
  s->reads = std::move(boot.reads);
  s->config = std::move(boot.config);
  s->state = Boot::Idle;
}

void NmtMaster::addReads(std::uint8_t id, std::vector<SlaveBoot::Read> reads) {
  Slave* s = find(id);
  if (s == nullptr) throw std::invalid_argument("NMT master: node " + std::to_string(id) + " is not a slave");
  s->reads.insert(s->reads.end(), std::make_move_iterator(reads.begin()), std::make_move_iterator(reads.end()));
}

void NmtMaster::addConfig(std::uint8_t id, std::vector<SlaveBoot::Write> writes) {
  Slave* s = find(id);
  if (s == nullptr) throw std::invalid_argument("NMT master: node " + std::to_string(id) + " is not a slave");
  s->config.insert(s->config.end(), std::make_move_iterator(writes.begin()), std::make_move_iterator(writes.end()));
}

void NmtMaster::loadPlan(Slave& s) {
  s.plan_error.clear();
  if (!bootFromDictionary(node_.od(), s.id, s.boot, &s.plan_error)) s.boot.writes.clear();
  s.boot.reads = s.reads;
  s.boot.config = s.config;
  const SlaveBoot& boot = s.boot;
  s.ops.clear();
  // CiA 302-2: the boot's first step reads 0x1000 whether a device type is expected or not - it also
  // proves the slave is there.
  for (const auto& k : kIdentity) {
    if (const auto& value = boot.*k.field)
      s.ops.push_back(Op{OpKind::Expect, k.index, k.sub, *value, 0});
    else if (k.index == kDeviceTypeIndex)
      s.ops.push_back(Op{OpKind::Present, k.index, k.sub, 0, 0});
  }
  for (std::size_t i = 0; i < boot.reads.size(); ++i)
    s.ops.push_back(Op{OpKind::Read, boot.reads[i].index, boot.reads[i].sub, 0, i});
  s.config_op = s.ops.size();
  configOps(s);
  // The application's configuration follows the dictionary's (Lely: 0x1F22, then Driver::OnConfig).
  for (std::size_t i = 0; i < boot.config.size(); ++i)
    s.ops.push_back(Op{OpKind::Config, boot.config[i].index, boot.config[i].sub, 0, i});
  // The start grace: its heartbeat period as the configuration sets it, else its consumer time.
  TimeUs period_us = node_.heartbeatConsumer().timeoutUs(s.id);
  for (const auto& w : boot.writes)
    if (w.index == kProducerHeartbeat && w.sub == 0 && w.data.size() == 2)
      period_us = static_cast<TimeUs>(w.data[0] | (w.data[1] << 8)) * 1000;
  s.start.grace_us = std::max<TimeUs>(kStartGraceFloorUs, kStartGracePeriods * period_us);
}

namespace {
bool sameEntry(const DcfEntry& a, const DcfEntry& b) { return a.index == b.index && a.sub == b.sub; }
}  // namespace

void NmtMaster::configOps(Slave& s) {
  const ConciseDcf& w = s.boot.writes;
  const auto at = [&w](std::size_t i) { return w.begin() + static_cast<std::ptrdiff_t>(i); };
  for (std::size_t i = 0; i < w.size(); ++i) {
    // A PDO COB-ID keeps the device's bit 30 (no RTR): a device without RTR may refuse it cleared.
    const bool first = std::none_of(w.begin(), at(i), [&](const DcfEntry& e) { return sameEntry(e, w[i]); });
    if (first && isPdoCobId(w[i].index, w[i].sub)) s.ops.push_back(Op{OpKind::KeepRtr, w[i].index, w[i].sub, 0, i});
    s.ops.push_back(Op{OpKind::Write, w[i].index, w[i].sub, 0, i});
  }
  // Read back what each entry holds in the end: its last write.
  for (std::size_t i = 0; i < w.size(); ++i) {
    const bool later = std::any_of(at(i + 1), w.end(), [&](const DcfEntry& e) { return sameEntry(e, w[i]); });
    if (!later) s.ops.push_back(Op{OpKind::Verify, w[i].index, w[i].sub, 0, i});
  }
}

NmtMaster::Slave* NmtMaster::find(std::uint8_t id) noexcept {
  const std::uint8_t k = id < slave_of_.size() ? slave_of_[id] : 0;
  return k == 0 ? nullptr : &slaves_[k - 1u];
}
const NmtMaster::Slave* NmtMaster::find(std::uint8_t id) const noexcept {
  return const_cast<NmtMaster*>(this)->find(id);
}

bool NmtMaster::mandatoryReady() const noexcept {
  return std::all_of(slaves_.begin(), slaves_.end(), [](const Slave& s) {
    return (s.boot.assignment & kAssignMandatory) == 0 || !bootable(s) || s.state == Boot::Done;
  });
}

bool NmtMaster::running(const Slave& s) const noexcept {
  const auto& hb = node_.heartbeatConsumer();
  return hb.alive(s.id) && hb.remoteState(s.id) == NmtState::Operational;
}

bool NmtMaster::mayStartAny() const noexcept {
  if (!begun_ || (startup_ & kStartupMaster) == 0 || (startup_ & kStartupNoSlaveStart) != 0) return false;
  return mandatoryReady();
}

bool NmtMaster::mayStart(const Slave& s) const noexcept {
  if (s.start.hold != 0) return false;
  if (bootable(s) && s.state != Boot::Done) return false;
  return mayStartAny();
}

void NmtMaster::startSlave(Slave& s, TimeUs now) noexcept {
  node_.sendNmt(NmtCommand::Start, s.id);
  s.start.sent = now;
  s.start.due = false;
  ++counters_.starts;
}

void NmtMaster::startReady(TimeUs now) noexcept {
  if ((startup_ & kStartupBroadcastStart) != 0 && !network_started_) {
    // 0x1F80 bit 1 (CiA 302-2 "start all nodes"): once the mandatory slaves are booted, one NMT start for
    // all if every slave may run; otherwise each that may by itself, now and as the others boot.
    if (!mayStartAny()) return;
    network_started_ = true;
    if (std::all_of(slaves_.begin(), slaves_.end(), [this](const Slave& s) { return mayStart(s); })) {
      node_.sendNmt(NmtCommand::Start, 0);
      for (auto& s : slaves_) s.start.sent = now, s.start.due = false;
      ++counters_.starts;
      return;
    }
  }
  // CiA 302-2 (as Lely's master): every booted slave is started, also one whose heartbeat already says
  // Operational (kept alive, or left running by another master).
  for (auto& s : slaves_)
    if (s.start.due && mayStart(s)) startSlave(s, now);
}

void NmtMaster::begin(TimeUs now) {
  const ObjectDictionary& od = node_.od();
  if (const Entry* e = od.find(kObjStartup, 0)) startup_ = e->get<std::uint32_t>();
  const Entry* boot_time = od.find(kObjBootTime, 0);
  boot_time_ms_ = boot_time != nullptr ? static_cast<std::uint32_t>(boot_time->asUnsigned()) : 0;
  for (auto& s : slaves_) {
    if (s.state != Boot::Running) loadPlan(s);
    s.start.due = !bootable(s);  // a boot slave is owed its start when its boot is done
  }
  begun_ = true;
  network_started_ = false;
  if ((startup_ & kStartupMaster) == 0) return;
  boot_deadline_ = boot_time_ms_ != 0 ? now + static_cast<TimeUs>(boot_time_ms_) * 1000 : kNever;
  // Every boot slave is booted at the master's start (CiA 302-2), whatever another master left in it.
  const bool all = resetAllAtOnce();
  if (all) node_.sendNmt(NmtCommand::ResetCommunication, 0);
  for (auto& s : slaves_)
    if (bootable(s) && s.state != Boot::Running) beginBoot(s, now, all);
  arm();
  poll(now);
  startReady(now);
}

// CiA 302-2 (and Lely's master): one NMT reset communication for all nodes unless a slave is kept alive
// (then each one not kept alive by itself). Not while a boot's SDO transfer is under way: that slave
// goes on where it is.
bool NmtMaster::resetAllAtOnce() const noexcept {
  const auto kept = [](const Slave& s) { return (s.boot.assignment & kAssignKeepAlive) != 0; };
  const auto mid = [](const Slave& s) { return s.state == Boot::Running; };
  const auto boot = [](const Slave& s) { return bootable(s); };
  return std::any_of(slaves_.begin(), slaves_.end(), boot) && std::none_of(slaves_.begin(), slaves_.end(), kept) &&
         std::none_of(slaves_.begin(), slaves_.end(), mid);
}

void NmtMaster::end() noexcept {
  begun_ = false;
  boot_deadline_ = kNever;
  for (auto& s : slaves_) {
    s.deadline = kNever;
    if (s.state == Boot::Checking || s.state == Boot::Resetting || s.state == Boot::Heartbeat ||
        s.state == Boot::Waiting)
      s.state = Boot::Idle;
  }
  arm();
}

void NmtMaster::poll(TimeUs) noexcept {
  if (std::any_of(slaves_.begin(), slaves_.end(), [](const Slave& s) { return s.state == Boot::Running; })) return;
  for (auto& s : slaves_) {
    if (s.state != Boot::Waiting) continue;
    if (node_.sdoClient().busy()) return;
    s.state = Boot::Running;
    runBoot(s);
    return;
  }
}

void NmtMaster::start(std::uint8_t id, TimeUs now) noexcept {
  if (Slave* s = find(id); s != nullptr && mayStart(*s)) startSlave(*s, now);
}

void NmtMaster::hold(std::uint8_t id, std::uint8_t reason) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return;
  const bool was = s->start.hold != 0;
  s->start.hold |= reason;
  if (was) return;
  node_.sendNmt(NmtCommand::EnterPreOperational, id);
  s->start.sent = kNever;
  s->start.due = true;
  ++counters_.holds;
}

void NmtMaster::release(std::uint8_t id, std::uint8_t reason, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr || (s->start.hold & reason) == 0) return;
  s->start.hold = static_cast<std::uint8_t>(s->start.hold & ~reason);
  if (s->start.due && mayStart(*s)) startSlave(*s, now);
}

std::uint8_t NmtMaster::holdReasons(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s ? s->start.hold : 0;
}

bool NmtMaster::down(std::uint8_t id, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return false;
  const NmtState st = node_.heartbeatConsumer().remoteState(id);
  if (st == NmtState::Stopped) return true;
  if (st != NmtState::PreOperational) return false;
  if (starting(id, now)) return false;
  if (mayStart(*s)) startSlave(*s, now);  // it did not follow the last start: send another
  return true;
}

bool NmtMaster::starting(std::uint8_t id, TimeUs now) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && s->start.sent != kNever && now - s->start.sent < s->start.grace_us;
}

TimeUs NmtMaster::startGraceUs(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s != nullptr ? s->start.grace_us : kStartGraceFloorUs;
}

bool NmtMaster::configured(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && (!bootable(*s) || s->state == Boot::Done);
}

bool NmtMaster::boots(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && bootable(*s);
}

bool NmtMaster::booting(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && s->state != Boot::Idle && s->state != Boot::Done && s->state != Boot::Failed;
}

const BootError* NmtMaster::bootError(std::uint8_t id) const noexcept {
  const Slave* s = find(id);
  return s != nullptr && s->state == Boot::Failed ? &s->error : nullptr;
}

void NmtMaster::onHeartbeat(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept {
  Slave* s = find(id);
  if (s == nullptr) return;
  const bool held = s->start.hold != 0;
  switch (ev) {
    case HeartbeatEvent::Timeout:
      s->lost = true;
      s->start.sent = kNever;
      emit(id, SlaveEvent::Lost, now);
      break;
    case HeartbeatEvent::BootUp:
      // A slave that booted lost its state and waits in Pre-operational: boot it and start it again.
      s->lost = false;
      emit(id, SlaveEvent::BootUp, now);
      if (bootable(*s)) {
        onBootEvent(*s, ev, st, now);
      } else {
        s->start.due = true;
        if (mayStart(*s)) startSlave(*s, now);
      }
      break;
    case HeartbeatEvent::Started:
      if (s->lost) {
        // Back after a timeout without a boot-up: re-boot it (reset communication); its boot-up boots and
        // starts it. One kept alive that reports Operational keeps its state and configuration.
        s->lost = false;
        if (!begun_) {
          // Not the master now: nothing to send.
        } else if ((s->boot.assignment & kAssignKeepAlive) != 0 && st == NmtState::Operational) {
          s->start.sent = kNever;
          ++counters_.kept_alive;
        } else {
          ++counters_.reboots;
          if (bootable(*s)) {
            s->identified = false;
            reset(*s, now);
          } else {
            node_.sendNmt(NmtCommand::ResetCommunication, id);
          }
        }
        break;
      }
      if (booting(id)) {
        onBootEvent(*s, ev, st, now);
        break;
      }
      if (st == NmtState::Operational)
        s->start.sent = kNever;
      else if (st == NmtState::PreOperational && mayStart(*s))
        startSlave(*s, now);
      break;
    case HeartbeatEvent::StateChanged:
      if (booting(id)) {
        onBootEvent(*s, ev, st, now);
        break;
      }
      if (st == NmtState::Operational) {
        s->start.sent = kNever;
      } else if (st == NmtState::PreOperational && !held) {
        emit(id, SlaveEvent::LeftOperational, now);
        if (mayStart(*s)) startSlave(*s, now);
      } else if (st == NmtState::Stopped && !held) {
        emit(id, SlaveEvent::Stopped, now);
      }
      break;
  }
}

}  // namespace pamc::canopen
