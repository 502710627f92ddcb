#include "canopen/emcy.hpp"

#include <cstring>

namespace pamc::canopen {

namespace {
constexpr std::uint16_t kErrorRegister = 0x1001;
constexpr std::uint16_t kErrorHistory = 0x1003;
constexpr std::uint16_t kEmcyCobId = 0x1014;
constexpr std::uint16_t kEmcyInhibit = 0x1015;
constexpr std::uint16_t kEmcyConsumer = 0x1028;
}  // namespace

std::uint8_t errorRegisterBit(std::uint16_t code) {
  switch (code >> 12) {
    case 0x2: return kErrRegCurrent;
    case 0x3: return kErrRegVoltage;
    case 0x4: return kErrRegTemperature;
    case 0x8: return kErrRegCommunication;
    case 0xF: return (code >> 8) == 0xFF ? kErrRegManufacturer : 0;
    default: return 0;
  }
}

void Emcy::registerHooks() {
  ObjectDictionary& od = ctx_.od;
  if (od.find(kEmcyCobId, 0) != nullptr) {
    // 11-bit identifiers only (bits 11-30 zero), and a valid EMCY may not use a restricted CAN-ID.
    od.addValidator(kEmcyCobId, 0, [](const Entry&, const std::uint8_t* d, std::size_t len) {
      if (len != 4) return kSdoOk;
      const std::uint32_t v = getU32(d);
      if ((v & 0x7FFFF800u) != 0) return kAbortValueRange;
      if ((v & 0x80000000u) == 0 && restrictedCobId(v & kStandardIdMask)) return kAbortValueRange;
      return kSdoOk;
    });
    od.addObserver(kEmcyCobId, 0, [this](Entry&) { configure(); });
  }
  if (od.find(kEmcyInhibit, 0) != nullptr) od.addObserver(kEmcyInhibit, 0, [this](Entry&) { configure(); });
  if (od.find(kErrorHistory, 0) != nullptr) {
    // CiA 301: only 0 may be written to 0x1003:00, which clears the history.
    od.addValidator(kErrorHistory, 0, [](const Entry&, const std::uint8_t* d, std::size_t len) {
      return len == 1 && d[0] != 0 ? kAbortValueRange : kSdoOk;
    });
  }
}

void Emcy::configure() {
  const Entry* id = ctx_.od.find(kEmcyCobId, 0);
  std::uint32_t v = id != nullptr ? static_cast<std::uint32_t>(id->asUnsigned()) : kEmcyCobIdBase + ctx_.node_id;
  enabled_ = (v & 0x80000000u) == 0;
  cob_id_ = v & kStandardIdMask;
  const Entry* inhibit = ctx_.od.find(kEmcyInhibit, 0);
  inhibit_us_ = inhibit != nullptr ? static_cast<TimeUs>(inhibit->asUnsigned()) * 100 : 0;

  for (std::uint32_t cob = kEmcyCobIdBase + 1; cob <= kEmcyCobIdBase + 127; ++cob)
    ctx_.dispatcher.unsubscribe(cob, this);
  if (const ObjectInfo* consumer = ctx_.od.object(kEmcyConsumer)) {
    for (std::size_t i = 1; i < consumer->count; ++i) {
      const Entry& e = ctx_.od.entries()[consumer->first + i];
      auto c = static_cast<std::uint32_t>(e.asUnsigned());
      if ((c & 0x80000000u) == 0) ctx_.dispatcher.subscribe<&Emcy::onFrame>(c & kStandardIdMask, this);
    }
  } else {
    for (std::uint32_t node = 1; node <= 127; ++node) {
      if (node == ctx_.node_id) continue;
      // Only free identifiers: a PDO or SYNC configured into this range keeps its frames.
      if (ctx_.dispatcher.available(kEmcyCobIdBase + node, this)) {
        ctx_.dispatcher.subscribe<&Emcy::onFrame>(kEmcyCobIdBase + node, this);
      }
    }
  }
}

void Emcy::updateRegister() {
  std::uint8_t reg = 0;
  for (std::size_t i = 0; i < active_count_; ++i)
    reg |= kErrRegGeneric | errorRegisterBit(static_cast<std::uint16_t>(active_[i] & 0xFFFFu));
  register_ = reg;
  if (Entry* e = ctx_.od.find(kErrorRegister, 0)) e->set<std::uint8_t>(reg);
}

bool Emcy::active(std::uint16_t code) const {
  for (std::size_t i = 0; i < active_count_; ++i) {
    if ((active_[i] & 0xFFFFu) == code) return true;
  }
  return false;
}

bool Emcy::activeFrom(std::uint32_t key) const {
  for (std::size_t i = 0; i < active_count_; ++i) {
    if (active_[i] == key) return true;
  }
  return false;
}

bool Emcy::report(std::uint16_t code, const std::uint8_t* manufacturer, std::uint8_t source) {
  const std::uint32_t key = code | static_cast<std::uint32_t>(source) << 16;
  if (code == kEmcyNoError || activeFrom(key)) return false;
  if (active_count_ < kMaxActive) active_[active_count_++] = key;
  updateRegister();
  if (const ObjectInfo* hist = ctx_.od.object(kErrorHistory)) {
    // Newest error first in 0x1003:01; older ones shift down, the oldest falls off.
    std::size_t slots = hist->count - 1;
    Entry* count = ctx_.od.find(kErrorHistory, 0);
    for (std::size_t i = slots; i > 1; --i) {
      Entry* dst = ctx_.od.find(kErrorHistory, static_cast<std::uint8_t>(i));
      Entry* src = ctx_.od.find(kErrorHistory, static_cast<std::uint8_t>(i - 1));
      if (dst != nullptr && src != nullptr) dst->write(src->data(), 4);
    }
    if (Entry* first = ctx_.od.find(kErrorHistory, 1)) {
      std::uint32_t v = code;
      if (manufacturer != nullptr)
        v |= static_cast<std::uint32_t>(manufacturer[0]) << 16 | static_cast<std::uint32_t>(manufacturer[1]) << 24;
      first->set<std::uint32_t>(v);
    }
    if (count != nullptr && count->get<std::uint8_t>() < slots)
      count->set<std::uint8_t>(count->get<std::uint8_t>() + 1);
  }
  return queue(code, manufacturer);
}

bool Emcy::clear(std::uint16_t code, std::uint8_t source, const std::uint8_t* manufacturer) {
  const std::uint32_t key = code | static_cast<std::uint32_t>(source) << 16;
  for (std::size_t i = 0; i < active_count_; ++i) {
    if (active_[i] != key) continue;
    active_[i] = active_[--active_count_];
    updateRegister();
    return queue(kEmcyNoError, manufacturer);
  }
  return false;
}

void Emcy::clearAll() {
  if (active_count_ == 0) return;
  active_count_ = 0;
  updateRegister();
  queue(kEmcyNoError, nullptr);
}

bool Emcy::queue(std::uint16_t code, const std::uint8_t* manufacturer) {
  if (!enabled_ || !ctx_.communicating()) return false;
  if (queue_count_ == kQueue) {
    ++ctx_.counters.emcy_dropped;
    return false;
  }
  Frame& f = queue_[(queue_head_ + queue_count_) % kQueue];
  f = Frame{};
  f.id = cob_id_;
  f.len = 8;
  putU16(f.data, code);
  f.data[2] = register_;
  if (manufacturer != nullptr) std::memcpy(f.data + 3, manufacturer, 5);
  ++queue_count_;
  flushQueue(ctx_.now);
  return true;
}

void Emcy::flushQueue(TimeUs now) {
  // The inhibit time (0x1015, 100 us units) spaces EMCY frames; later ones wait in the queue.
  while (queue_count_ > 0 && (!has_sent_ || now >= last_tx_us_ + inhibit_us_)) {
    ctx_.send(queue_[queue_head_]);
    queue_head_ = (queue_head_ + 1) % kQueue;
    --queue_count_;
    has_sent_ = true;
    last_tx_us_ = now;
  }
}

void Emcy::advance(TimeUs now) { flushQueue(now); }

TimeUs Emcy::nextDeadline() const { return queue_count_ > 0 ? last_tx_us_ + inhibit_us_ : kNever; }

void Emcy::onFrame(const Frame& f, TimeUs now) {
  if (f.len != 8) {
    ++ctx_.counters.wrong_length;
    return;
  }
  if (!hook_) return;
  EmcyMessage m;
  m.node_id = static_cast<std::uint8_t>(f.id - kEmcyCobIdBase);
  m.error_code = getU16(f.data);
  m.error_register = f.data[2];
  std::memcpy(m.manufacturer, f.data + 3, 5);
  hook_(m, now);
}

}  // namespace pamc::canopen
