#include "canopen/sync.hpp"

#include <algorithm>

namespace pamc::canopen {

namespace {
constexpr std::uint16_t kSyncCobId = 0x1005;
constexpr std::uint16_t kCommCyclePeriod = 0x1006;
constexpr std::uint16_t kSyncOverflow = 0x1019;
constexpr std::uint16_t kSyncWindow = 0x1007;
}  // namespace

void Sync::registerHooks() {
  ObjectDictionary& od = ctx_.od;
  if (od.find(kSyncCobId, 0) != nullptr) {
    od.addValidator(kSyncCobId, 0, [](const Entry&, const std::uint8_t* d, std::size_t len) {
      if (len != 4) return kSdoOk;
      std::uint32_t v = getU32(d);
      if ((v & 0x20000000u) != 0 || (v & 0x1FFFF800u) != 0) return kAbortValueRange;  // 29-bit SYNC unsupported
      if (restrictedCobId(v & kStandardIdMask)) return kAbortValueRange;
      return kSdoOk;
    });
    od.addObserver(kSyncCobId, 0, [this](Entry&) { configure(ctx_.now); });
  }
  if (od.find(kCommCyclePeriod, 0) != nullptr) {
    od.addObserver(kCommCyclePeriod, 0, [this](Entry&) { configure(ctx_.now); });
  }
  if (od.find(kSyncWindow, 0) != nullptr) {
    od.addObserver(kSyncWindow, 0, [this](Entry& e) { ctx_.sync_window_us = static_cast<TimeUs>(e.asUnsigned()); });
  }
  if (od.find(kSyncOverflow, 0) != nullptr) {
    // CiA 301: the counter overflow may only change while no SYNC is produced (period 0).
    od.addValidator(kSyncOverflow, 0, [this](const Entry&, const std::uint8_t* d, std::size_t len) {
      if (len != 1) return kSdoOk;
      if (d[0] == 1 || d[0] > 240) return kAbortValueRange;
      if (period_us_ != 0) return kAbortDeviceState;
      return kSdoOk;
    });
    od.addObserver(kSyncOverflow, 0, [this](Entry&) { configure(ctx_.now); });
  }
}

void Sync::configure(TimeUs now) {
  const Entry* id = ctx_.od.find(kSyncCobId, 0);
  const Entry* period = ctx_.od.find(kCommCyclePeriod, 0);
  const Entry* overflow = ctx_.od.find(kSyncOverflow, 0);
  std::uint32_t v = id != nullptr ? static_cast<std::uint32_t>(id->asUnsigned()) : 0x80;
  if (subscribed_) ctx_.dispatcher.unsubscribe(cob_id_, this);
  subscribed_ = false;
  cob_id_ = v & kStandardIdMask;
  producer_ = (v & kSyncProducerBit) != 0;
  period_us_ = period != nullptr ? static_cast<TimeUs>(period->asUnsigned()) : 0;
  overflow_ = overflow != nullptr ? static_cast<std::uint8_t>(overflow->asUnsigned()) : 0;
  const Entry* window = ctx_.od.find(kSyncWindow, 0);
  ctx_.sync_window_us = window != nullptr ? static_cast<TimeUs>(window->asUnsigned()) : 0;
  // CiA 301 leaves the SYNC timeout to the device; 1.5 periods as CANopenNode does.
  timeout_us_ = !producer_ && period_us_ > 0 ? period_us_ + period_us_ / 2 : 0;
  // A producer does not receive its own frame; it runs the SYNC handler when it sends.
  if (!producer_ && id != nullptr) {
    subscribed_ = ctx_.dispatcher.subscribe<&Sync::onFrame>(cob_id_, this);
  }
  restart(now);
}

void Sync::restart(TimeUs now) {
  counter_ = 0;
  next_us_ = producer_ && period_us_ > 0 ? now + period_us_ : kNever;
  // Monitoring starts with the first SYNC after (re)configuration.
  last_rx_us_ = kNever;
  timed_out_ = false;
  ctx_.last_sync_us = kNever;
}

void Sync::onFrame(const Frame& f, TimeUs now) {
  // With a counter (0x1019 > 0) a SYNC carries one byte, otherwise none.
  if (f.len != (overflow_ > 0 ? 1 : 0)) {
    ++ctx_.counters.wrong_length;
    ++wrong_length_;
    return;
  }
  if (!ctx_.communicating()) {
    ++ctx_.counters.ignored_in_state;
    return;
  }
  ++consumed_;
  last_rx_us_ = now;
  timed_out_ = false;
  ctx_.last_sync_us = now;
  emit(overflow_ > 0 ? f.data[0] : 0, now);
}

TimeUs Sync::monitorDeadline() const {
  if (timeout_us_ == 0 || last_rx_us_ == kNever || timed_out_ || !ctx_.communicating()) return kNever;
  return last_rx_us_ + timeout_us_;
}

void Sync::advance(TimeUs now) {
  const TimeUs monitor = monitorDeadline();
  if (monitor != kNever && now >= monitor) {
    timed_out_ = true;
    ++ctx_.counters.sync_timeouts;
    if (timeout_hook_) timeout_hook_(now);
  }
  if (next_us_ == kNever || now < next_us_) return;
  // Deadlines stay on the grid start + k * period whatever the wake-up jitter, so SYNC never drifts.
  next_us_ += period_us_;
  if (next_us_ <= now) {
    TimeUs missed = (now - next_us_) / period_us_ + 1;
    ctx_.counters.sync_overruns += static_cast<std::uint64_t>(missed);
    next_us_ += missed * period_us_;
  }
  if (!ctx_.communicating()) return;
  Frame f;
  f.id = cob_id_;
  if (overflow_ > 0) {
    counter_ = counter_ >= overflow_ ? 1 : static_cast<std::uint8_t>(counter_ + 1);
    f.len = 1;
    f.data[0] = counter_;
  }
  // A SYNC that cannot leave before the next one is due would only start a late cycle: drop it then.
  ctx_.sendUntil(f, now + period_us_);
  ++produced_;
  ctx_.last_sync_us = now;
  emit(overflow_ > 0 ? counter_ : 0, now);
}

TimeUs Sync::nextDeadline() const { return std::min(next_us_, monitorDeadline()); }

}  // namespace pamc::canopen
