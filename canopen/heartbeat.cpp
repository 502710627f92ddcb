#include "canopen/heartbeat.hpp"

#include <algorithm>

#include "canopen/nmt.hpp"

namespace pamc::canopen {

namespace {
constexpr std::uint16_t kConsumerHeartbeat = 0x1016;
constexpr std::uint16_t kProducerHeartbeat = 0x1017;
}  // namespace

void HeartbeatProducer::registerHooks() {
  if (ctx_.od.find(kProducerHeartbeat, 0) == nullptr) return;
  ctx_.od.addObserver(kProducerHeartbeat, 0, [this](Entry&) { configure(ctx_.now); });
}

void HeartbeatProducer::configure(TimeUs now) {
  const Entry* e = ctx_.od.find(kProducerHeartbeat, 0);
  period_us_ = e != nullptr ? static_cast<TimeUs>(e->asUnsigned()) * 1000 : 0;
  next_us_ = period_us_ > 0 ? now + period_us_ : kNever;
}

void HeartbeatProducer::advance(TimeUs now) {
  if (next_us_ == kNever || now < next_us_) return;
  if (ctx_.state != NmtState::Initialising) {
    Frame f;
    f.id = kHeartbeatCobIdBase + ctx_.node_id;
    f.len = 1;
    f.data[0] = static_cast<std::uint8_t>(ctx_.state);
    ctx_.send(f);
  }
  next_us_ += period_us_;
  // A late wake-up sends one heartbeat, not a burst of the missed ones.
  if (next_us_ <= now) next_us_ = now + period_us_;
}

const char* heartbeatEventName(HeartbeatEvent e) {
  switch (e) {
    case HeartbeatEvent::Started: return "started";
    case HeartbeatEvent::Timeout: return "timeout";
    case HeartbeatEvent::BootUp: return "boot-up";
    case HeartbeatEvent::StateChanged: return "state changed";
  }
  return "?";
}

void HeartbeatConsumer::registerHooks() {
  const Entry* count = ctx_.od.find(kConsumerHeartbeat, 0);
  if (count == nullptr) return;
  consumer_slots_ = count->asUnsigned();
  slots_.resize(consumer_slots_ + watched_.size());
  // Two entries for the same node are refused (CiA 301: general parameter incompatibility).
  ctx_.od.addValidator(kConsumerHeartbeat, [this](const Entry& e, const std::uint8_t* d, std::size_t len) {
    if (e.subIndex() == 0 || len != 4) return kSdoOk;
    std::uint32_t v = getU32(d);
    std::uint32_t node = (v >> 16) & 0xFF;
    if ((v >> 24) != 0 || node > 127) return kAbortValueRange;
    if (node == 0 || (v & 0xFFFF) == 0) return kSdoOk;
    for (std::size_t i = 1; i <= consumer_slots_; ++i) {
      const Entry* other = ctx_.od.find(kConsumerHeartbeat, static_cast<std::uint8_t>(i));
      if (other == nullptr || other == &e) continue;
      auto ov = static_cast<std::uint32_t>(other->asUnsigned());
      if (((ov >> 16) & 0xFF) == node && (ov & 0xFFFF) != 0) return kAbortParameterIncompatible;
    }
    return kSdoOk;
  });
  ctx_.od.addObserver(kConsumerHeartbeat, [this](Entry&) { configure(); });
}

void HeartbeatConsumer::configure() {
  stale_ = true;
  for (Slot& s : slots_) {
    if (s.status != Status::Unused) ctx_.dispatcher.unsubscribe(kHeartbeatCobIdBase + s.node_id, this);
    s = Slot{};
  }
  slot_of_.fill(0);
  for (std::size_t i = 0; i < consumer_slots_; ++i) {
    const Entry* e = ctx_.od.find(kConsumerHeartbeat, static_cast<std::uint8_t>(i + 1));
    if (e == nullptr) continue;
    auto v = static_cast<std::uint32_t>(e->asUnsigned());
    auto node = static_cast<std::uint8_t>((v >> 16) & 0x7F);
    std::uint32_t time_ms = v & 0xFFFF;
    if (node == 0 || time_ms == 0 || node == ctx_.node_id) continue;
    if (slotFor(node) != nullptr) continue;  // duplicates are refused on SDO write; ignore one from the EDS
    Slot& s = slots_[i];
    s.node_id = node;
    slot_of_[node] = static_cast<std::uint16_t>(i + 1);
    s.timeout_us = static_cast<TimeUs>(time_ms) * 1000;
    s.status = Status::Waiting;
    ctx_.dispatcher.subscribe<&HeartbeatConsumer::onFrame>(kHeartbeatCobIdBase + node, this);
  }
  for (std::size_t k = 0; k < watched_.size(); ++k) {
    const std::uint8_t node = watched_[k];
    if (node == ctx_.node_id || node >= slot_of_.size() || slotFor(node) != nullptr) continue;
    Slot& s = slots_[consumer_slots_ + k];
    s.node_id = node;
    slot_of_[node] = static_cast<std::uint16_t>(consumer_slots_ + k + 1);
    s.status = Status::Waiting;
    ctx_.dispatcher.subscribe<&HeartbeatConsumer::onFrame>(kHeartbeatCobIdBase + node, this);
  }
}

void HeartbeatConsumer::watch(std::uint8_t node_id) {
  if (std::find(watched_.begin(), watched_.end(), node_id) != watched_.end()) return;
  watched_.push_back(node_id);
  slots_.resize(consumer_slots_ + watched_.size());
  configure();
}

const HeartbeatConsumer::Slot* HeartbeatConsumer::slotFor(std::uint8_t node_id) const {
  const std::uint16_t k = node_id < slot_of_.size() ? slot_of_[node_id] : 0;
  return k == 0 ? nullptr : &slots_[k - 1u];
}

void HeartbeatConsumer::onFrame(const Frame& f, TimeUs now) {
  stale_ = true;
  if (f.len != 1) {
    ++ctx_.counters.wrong_length;
    return;
  }
  if (ctx_.state == NmtState::Initialising) return;
  Slot* s = slotFor(static_cast<std::uint8_t>(f.id - kHeartbeatCobIdBase));
  if (s == nullptr) return;
  auto state = static_cast<NmtState>(f.data[0] & 0x7F);
  if (state == NmtState::Initialising) {
    // Boot-up: the node restarted; wait for its first heartbeat before timing it again.
    s->state = state;
    s->status = Status::Waiting;
    emit(*s, HeartbeatEvent::BootUp, now);
    return;
  }
  NmtState old = s->state;
  s->state = state;
  s->last_us = now;
  if (s->status != Status::Active) {
    s->status = Status::Active;
    emit(*s, HeartbeatEvent::Started, now);
  } else if (old != state) {
    emit(*s, HeartbeatEvent::StateChanged, now);
  }
}

void HeartbeatConsumer::advance(TimeUs now) {
  if (now < nextDeadline()) return;
  stale_ = true;
  for (Slot& s : slots_) {
    if (s.status == Status::Active && s.timeout_us > 0 && now >= s.last_us + s.timeout_us) {
      s.status = Status::TimedOut;
      emit(s, HeartbeatEvent::Timeout, now);
    }
  }
}

TimeUs HeartbeatConsumer::nextDeadline() const {
  if (!stale_) return next_;
  TimeUs next = kNever;
  for (const Slot& s : slots_) {
    if (s.status == Status::Active && s.timeout_us > 0 && s.last_us + s.timeout_us < next)
      next = s.last_us + s.timeout_us;
  }
  next_ = next;
  stale_ = false;
  return next;
}

NmtState HeartbeatConsumer::remoteState(std::uint8_t node_id) const {
  const Slot* s = slotFor(node_id);
  return s != nullptr ? s->state : NmtState::Initialising;
}

bool HeartbeatConsumer::timedOut(std::uint8_t node_id) const {
  const Slot* s = slotFor(node_id);
  return s != nullptr && s->status == Status::TimedOut;
}

bool HeartbeatConsumer::alive(std::uint8_t node_id) const {
  const Slot* s = slotFor(node_id);
  return s != nullptr && s->status == Status::Active;
}

TimeUs HeartbeatConsumer::timeoutUs(std::uint8_t node_id) const {
  const Slot* s = slotFor(node_id);
  return s != nullptr ? s->timeout_us : 0;
}

std::size_t HeartbeatConsumer::monitoredCount() const {
  std::size_t n = 0;
  for (const Slot& s : slots_) n += s.status != Status::Unused && s.timeout_us > 0 ? 1 : 0;
  return n;
}

}  // namespace pamc::canopen
