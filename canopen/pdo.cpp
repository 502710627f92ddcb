#include "canopen/pdo.hpp"

#include <algorithm>
#include <cstdio>
#include <cstring>

namespace pamc::canopen {

namespace {

constexpr std::uint8_t kCobIdSub = 1;
constexpr std::uint8_t kTypeSub = 2;
constexpr std::uint8_t kInhibitSub = 3;
constexpr std::uint8_t kEventTimerSub = 5;
constexpr std::uint8_t kSyncStartSub = 6;

std::uint64_t readOr(const ObjectDictionary& od, std::uint16_t index, std::uint8_t sub, std::uint64_t fallback) {
  const Entry* e = od.find(index, sub);
  return e != nullptr ? e->asUnsigned() : fallback;
}

bool typeAllowed(std::uint8_t t) { return t <= kPdoSyncMax || t == kPdoEventManufacturer || t == kPdoEventProfile; }

std::string pdoName(const char* kind, unsigned number, std::uint16_t map_index) {
  char buf[48];
  std::snprintf(buf, sizeof buf, "%s%u (0x%04X)", kind, number, static_cast<unsigned>(map_index));
  return buf;
}

std::string mappingText(std::uint32_t v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "0x%08X (0x%04X:%02X, %u bits)", static_cast<unsigned>(v),
                static_cast<unsigned>(v >> 16), static_cast<unsigned>((v >> 8) & 0xFF),
                static_cast<unsigned>(v & 0xFF));
  return buf;
}

// Validators shared by RPDO and TPDO parameters. valid() tells whether the PDO currently exists.
template <class Pdo>
void installHooks(NodeContext& ctx, Pdo* pdo, std::uint16_t comm, std::uint16_t map_index, bool receive) {
  ObjectDictionary& od = ctx.od;
  od.addValidator(comm, [&ctx, pdo, receive](const Entry& e, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
    if (len == 0 || len > 4) return kSdoOk;  // the length check of remoteWrite reports this
    std::uint32_t v = 0;
    std::memcpy(&v, d, len);
    switch (e.subIndex()) {
      case kCobIdSub: {
        if ((v & kPdoExtendedBit) != 0 || (v & 0x1FFFF800u) != 0) return kAbortValueRange;
        bool new_valid = (v & kPdoInvalidBit) == 0;
        std::uint32_t id = v & kStandardIdMask;
        // CiA 301: the identifier of an existing PDO may not change; disable it (bit 31) first.
        if (pdo->valid() && new_valid && id != pdo->cobId()) return kAbortValueRange;
        if (new_valid && (id == 0 || (receive && !ctx.dispatcher.available(id, pdo)))) {
          return kAbortParameterIncompatible;
        }
        if (new_valid && restrictedCobId(id)) return kAbortValueRange;
        return kSdoOk;
      }
      case kTypeSub: return typeAllowed(static_cast<std::uint8_t>(v)) ? kSdoOk : kAbortValueRange;
      case kInhibitSub: return pdo->valid() ? kAbortDeviceState : kSdoOk;
      case kSyncStartSub:
        if (pdo->valid()) return kAbortDeviceState;
        return v <= kPdoSyncMax ? kSdoOk : kAbortValueRange;
      default: return kSdoOk;
    }
  });
  // Mapping follows the CiA 301 procedure: disable PDO, sub0 = 0, write entries, sub0 = n, enable.
  od.addValidator(
      map_index,
      [&ctx, pdo, map_index, receive](const Entry& e, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
        if (pdo->valid()) return kAbortDeviceState;
        if (e.subIndex() == 0) {
          if (len != 1) return kSdoOk;
          if (d[0] > 8) return kAbortValueRange;
          unsigned total = 0;
          for (std::uint8_t i = 1; i <= d[0]; ++i) {
            const Entry* m = ctx.od.find(map_index, i);
            if (m == nullptr) return kAbortNoSubIndex;
            std::uint8_t bytes = 0;
            std::uint32_t code = PdoMap::check(ctx.od, static_cast<std::uint32_t>(m->asUnsigned()), receive, &bytes);
            if (code != kSdoOk) return code;
            total += bytes;
          }
          return total > 8 ? kAbortPdoLength : kSdoOk;
        }
        if (len != 4) return kSdoOk;
        if (readOr(ctx.od, map_index, 0, 0) != 0) return kAbortDeviceState;
        std::uint32_t v = getU32(d);
        return v == 0 ? kSdoOk : PdoMap::check(ctx.od, v, receive, nullptr);
      });
  od.addObserver(comm, [pdo](Entry&) { pdo->reconfigure(); });
  od.addObserver(map_index, [pdo](Entry&) { pdo->reconfigure(); });
}

}  // namespace

// ---- Parameters ----

std::uint32_t readPdoMapping(const ObjectDictionary& od, std::uint16_t map_index, PdoMapping& out) {
  out = PdoMapping{};
  const Entry* count = od.find(map_index, 0);
  if (count == nullptr) return kAbortNoObject;
  out.count = count->asUnsigned();
  if (out.count > 8) return kAbortValueRange;
  for (std::uint8_t i = 1; i <= out.count; ++i) {
    const Entry* m = od.find(map_index, i);
    if (m == nullptr) return kAbortNoSubIndex;
    out.entries[out.read++].value = static_cast<std::uint32_t>(m->asUnsigned());
  }
  return kSdoOk;
}

std::uint32_t readPdoCobId(const ObjectDictionary& od, std::uint16_t comm_index) {
  return static_cast<std::uint32_t>(readOr(od, comm_index, kCobIdSub, kPdoInvalidBit));
}

// ---- PdoMap ----

std::uint32_t PdoMap::check(const ObjectDictionary& od, std::uint32_t value, bool receive, std::uint8_t* bytes) {
  const PdoMappingEntry m{value};
  const std::uint16_t index = m.index();
  const std::uint8_t sub = m.sub(), bits = m.bits();
  if (bits == 0 || bits % 8 != 0) return kAbortNotMappable;  // bit-level mapping is not supported
  std::size_t size = 0;
  if (m.dummy()) {
    // Dummy entry: an RPDO may skip bytes of a basic type it does not need.
    if (!receive) return kAbortNotMappable;
    size = dataTypeSize(static_cast<DataType>(index));
  } else {
    const Entry* e = od.find(index, sub);
    if (e == nullptr) return od.hasObject(index) ? kAbortNoSubIndex : kAbortNoObject;
    if (!e->pdoMappable() || !isNumeric(e->dataType())) return kAbortNotMappable;
    if (receive ? !e->writable() : !e->readable()) return kAbortNotMappable;
    size = dataTypeSize(e->dataType());
  }
  if (size * 8 != bits) return kAbortNotMappable;
  if (bytes != nullptr) *bytes = static_cast<std::uint8_t>(size);
  return kSdoOk;
}

std::uint32_t PdoMap::build(ObjectDictionary& od, std::uint16_t map_index, bool receive, std::uint32_t* bad_value) {
  clear();
  PdoMapping mapping;
  const std::uint32_t read = readPdoMapping(od, map_index, mapping);
  if (read == kAbortNoObject || read == kAbortValueRange) return read;
  unsigned total = 0;
  std::array<Field, 8> fields{};
  for (std::uint8_t i = 0; i < mapping.read; ++i) {
    const PdoMappingEntry m = mapping.entries[i];
    std::uint8_t bytes = 0;
    std::uint32_t code = check(od, m.value, receive, &bytes);
    if (code == kSdoOk && total + bytes > 8) code = kAbortPdoLength;
    if (code != kSdoOk) {
      if (bad_value != nullptr) *bad_value = m.value;
      return code;
    }
    Entry* target = m.dummy() ? nullptr : od.find(m.index(), m.sub());
    fields[i] = Field{target != nullptr ? const_cast<std::uint8_t*>(target->data()) : nullptr, bytes};
    total += bytes;
  }
  if (read != kSdoOk) return read;  // an entry missing after those that passed
  fields_ = fields;
  count_ = mapping.read;
  size_ = static_cast<std::uint8_t>(total);
  return kSdoOk;
}

void PdoMap::encode(std::uint8_t* out) const {
  for (std::uint8_t i = 0; i < count_; ++i) {
    const Field& f = fields_[i];
    if (f.ptr != nullptr)
      std::memcpy(out, f.ptr, f.len);
    else
      std::memset(out, 0, f.len);
    out += f.len;
  }
}

void PdoMap::decode(const std::uint8_t* in) const {
  for (std::uint8_t i = 0; i < count_; ++i) {
    const Field& f = fields_[i];
    if (f.ptr != nullptr) std::memcpy(f.ptr, in, f.len);
    in += f.len;
  }
}

// ---- PdoBase ----

std::uint32_t PdoBase::readCommParameters() {
  const std::uint32_t v = readPdoCobId(ctx_.od, comm_);
  cob_id_ = v & kStandardIdMask;
  type_ = static_cast<std::uint8_t>(readOr(ctx_.od, comm_, kTypeSub, kPdoEventManufacturer));
  event_timer_us_ = static_cast<TimeUs>(readOr(ctx_.od, comm_, kEventTimerSub, 0)) * 1000;
  valid_ = false;
  ++ctx_.pdo_epoch;  // valid_ may change: the node's list of live PDOs is due again
  return v;
}

std::uint32_t PdoBase::buildMap(bool receive) {
  std::uint32_t code = map_.build(ctx_.od, map_index_, receive, nullptr);
  if (code != kSdoOk) return code;
  return typeAllowed(type_) ? kSdoOk : kAbortValueRange;
}

void PdoBase::throwUnlessOk(std::uint32_t code, bool receive) const {
  if (code == kSdoOk) return;
  std::uint32_t bad = 0;
  PdoMap probe;
  probe.build(ctx_.od, map_index_, receive, &bad);
  throw OdError(pdoName(receive ? "RPDO" : "TPDO", number_, map_index_) + ": " + sdoAbortText(code) +
                (bad != 0 ? " (entry " + mappingText(bad) + ")" : std::string()));
}

// ---- Rpdo ----

void Rpdo::registerHooks() { installHooks(ctx_, this, comm_, map_index_, true); }

std::uint32_t Rpdo::reconfigure() {
  if (subscribed_) ctx_.dispatcher.unsubscribe(cob_id_, this);
  subscribed_ = false;
  const std::uint32_t v = readCommParameters();
  reset();
  std::uint32_t code = buildMap(true);
  if (code != kSdoOk) return code;
  if (!enabledBy(v)) return kSdoOk;
  subscribed_ = ctx_.dispatcher.subscribe<&Rpdo::onFrame>(cob_id_, this);
  if (!subscribed_) return kAbortParameterIncompatible;
  valid_ = true;
  return kSdoOk;
}

bool Rpdo::acceptSynchronous(const Frame& f, TimeUs now) {
  // CiA 301: synchronous PDOs belong in the synchronous window after the SYNC; later ones are discarded.
  if (ctx_.sync_window_us > 0 && ctx_.last_sync_us != kNever && now - ctx_.last_sync_us > ctx_.sync_window_us) {
    ++stats_.late;
    ++ctx_.counters.rpdo_late;
    return false;
  }
  if (rx_.conflict) {
    ++stats_.conflicts;
    ++ctx_.counters.rpdo_conflicts;
    return false;
  }
  if (!rx_.rx_since_sync) return true;
  if (rx_.has_pending && std::memcmp(rx_.pending, f.data, f.len) == 0) {
    ++stats_.duplicates;
    ++ctx_.counters.rpdo_duplicates;
    return false;
  }
  // Two different values for one cycle: neither can be trusted, the cycle counts as missing.
  ++stats_.conflicts;
  ++ctx_.counters.rpdo_conflicts;
  rx_.conflict = true;
  rx_.has_pending = false;
  rx_.rx_since_sync = false;
  return false;
}

void Rpdo::onFrame(const Frame& f, TimeUs now) {
  if (!valid_) return;
  if (!ctx_.operational()) {
    ++ctx_.counters.ignored_in_state;
    return;
  }
  if (f.len != map_.size()) {
    ++stats_.wrong_length;
    ++ctx_.counters.wrong_length;
    ++ctx_.counters.rpdo_wrong_length;
    return;
  }
  if (synchronous() && !acceptSynchronous(f, now)) return;
  ++stats_.received;
  rx_.rx_since_sync = true;
  rx_.timed_out = false;
  rx_.last_rx_us = now;
  if (synchronous()) {
    // CiA 301: synchronous RPDO data take effect at the next SYNC.
    std::memcpy(rx_.pending, f.data, f.len);
    rx_.has_pending = true;
  } else {
    map_.decode(f.data);
  }
}

void Rpdo::onSync(TimeUs /*now*/) {
  if (!valid_ || !ctx_.operational()) return;
  if (rx_.has_pending) {
    map_.decode(rx_.pending);
    rx_.has_pending = false;
  }
  if (rx_.rx_since_sync) {
    rx_.syncs_since_rx = 0;
  } else if (rx_.syncs_since_rx < UINT32_MAX) {
    ++rx_.syncs_since_rx;
  }
  rx_.rx_since_sync = false;
  rx_.conflict_latched = rx_.conflict;
  rx_.conflict = false;
}

void Rpdo::advance(TimeUs now) {
  TimeUs d = nextDeadline();
  if (d == kNever || now < d) return;
  rx_.timed_out = true;
  if (timeout_hook_) timeout_hook_(number_, now);
}

TimeUs Rpdo::nextDeadline() const {
  // Deadline monitoring starts with the first reception (as CANopenNode does) and fires once.
  if (!valid_ || event_timer_us_ == 0 || rx_.timed_out || rx_.last_rx_us == kNever || !ctx_.operational()) {
    return kNever;
  }
  return rx_.last_rx_us + event_timer_us_;
}

// ---- Tpdo ----

void Tpdo::registerHooks() { installHooks(ctx_, this, comm_, map_index_, false); }

std::uint32_t Tpdo::reconfigure() {
  const std::uint32_t v = readCommParameters();
  inhibit_us_ = static_cast<TimeUs>(readOr(ctx_.od, comm_, kInhibitSub, 0)) * 100;
  sync_start_ = static_cast<std::uint8_t>(readOr(ctx_.od, comm_, kSyncStartSub, 0));
  std::uint32_t code = buildMap(false);
  if (code != kSdoOk) return code;
  valid_ = enabledBy(v) && cob_id_ != 0;
  start(ctx_.now);
  return kSdoOk;
}

void Tpdo::start(TimeUs now) {
  sync_count_ = 0;
  waiting_for_start_ = sync_start_ != 0;
  pending_ = eventDriven();
  has_sent_ = false;
  last_tx_us_ = now;
}

void Tpdo::transmit(TimeUs now) {
  Frame f;
  f.id = cob_id_;
  f.len = map_.size();
  map_.encode(f.data);
  // CiA 301: a synchronous TPDO not sent within the synchronous window (0x1007) is discarded.
  if (synchronous() && ctx_.sync_window_us > 0 && ctx_.last_sync_us != kNever) {
    ctx_.sendUntil(f, ctx_.last_sync_us + ctx_.sync_window_us);
  } else {
    ctx_.send(f);
  }
  std::memcpy(last_, f.data, f.len);
  has_sent_ = true;
  last_tx_us_ = now;
  pending_ = false;
  ++sent_;
}

bool Tpdo::changed() const {
  if (!change_of_state_) return false;
  if (!has_sent_) return true;
  std::uint8_t now_data[8];
  map_.encode(now_data);
  return std::memcmp(now_data, last_, map_.size()) != 0;
}

void Tpdo::onSync(std::uint8_t counter, TimeUs now) {
  if (!valid_ || !ctx_.operational() || !synchronous()) return;
  if (type_ == kPdoSyncAcyclic) {
    if (pending_ || (change_of_state_ && changed())) transmit(now);
    return;
  }
  if (waiting_for_start_) {
    // With a SYNC counter, the first transmission waits for the configured start value (0x18xx:06).
    if (counter != sync_start_) return;
    waiting_for_start_ = false;
    sync_count_ = 0;
    transmit(now);
    return;
  }
  if (++sync_count_ >= type_) {
    sync_count_ = 0;
    transmit(now);
  }
}

void Tpdo::advance(TimeUs now) {
  if (!valid_ || !ctx_.operational() || !eventDriven()) return;
  if (event_timer_us_ > 0 && now >= last_tx_us_ + event_timer_us_) pending_ = true;
  if (!pending_ && changed()) pending_ = true;
  if (pending_ && (!has_sent_ || now >= last_tx_us_ + inhibit_us_)) transmit(now);
}

TimeUs Tpdo::nextDeadline() const {
  if (!valid_ || !ctx_.operational() || !eventDriven()) return kNever;
  TimeUs earliest = has_sent_ ? last_tx_us_ + inhibit_us_ : ctx_.now;
  if (pending_ || changed()) return earliest;
  if (event_timer_us_ > 0) return std::max(earliest, last_tx_us_ + event_timer_us_);
  return kNever;
}

}  // namespace pamc::canopen
