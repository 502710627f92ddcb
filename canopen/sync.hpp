// SYNC (CiA 301, 7.2.5): producer on absolute deadlines (period 0x1006 in us, COB-ID 0x1005,
// counter overflow 0x1019) and consumer. A consumer with a period in 0x1006 monitors the SYNC: no SYNC
// within 1.5 periods of the last one is a timeout (reported once, cleared by the next SYNC). The
// synchronous window 0x1007 is kept in the node context for the RPDOs.
#pragma once

#include <cstdint>
#include <functional>

#include "canopen/service.hpp"

namespace pamc::canopen {

inline constexpr std::uint32_t kSyncProducerBit = 0x40000000;  // 0x1005 bit 30: this node generates SYNC

class Sync {
 public:
  // Runs for every SYNC this node produces or consumes (counter 0 when 0x1019 is 0).
  using Handler = std::function<void(std::uint8_t counter, TimeUs now)>;
  // Consumer: the SYNC stopped (no SYNC within 1.5 periods of 0x1006 after the last one).
  using TimeoutHook = std::function<void(TimeUs now)>;

  explicit Sync(NodeContext& ctx) : ctx_(ctx) {}
  void setHandler(Handler h) { handler_ = std::move(h); }
  void setTimeoutHook(TimeoutHook h) { timeout_hook_ = std::move(h); }
  // Installs SDO validators/observers on 0x1005, 0x1006, 0x1019 (configuration time).
  void registerHooks();
  // Reads 0x1005/0x1006/0x1019 and subscribes to the SYNC COB-ID; a producer starts its grid at now.
  void configure(TimeUs now);
  // Restarts the producer grid: first SYNC one period after now, counter back to 1.
  void restart(TimeUs now);

  void onFrame(const Frame& f, TimeUs now);
  void advance(TimeUs now);
  TimeUs nextDeadline() const;

  bool producer() const { return producer_; }
  std::uint32_t cobId() const { return cob_id_; }
  TimeUs periodUs() const { return period_us_; }
  std::uint8_t overflow() const { return overflow_; }
  std::uint64_t produced() const { return produced_; }
  std::uint64_t consumed() const { return consumed_; }
  // Consumer monitoring: true from a timeout until the next SYNC.
  bool timedOut() const { return timed_out_; }
  TimeUs timeoutUs() const { return timeout_us_; }
  TimeUs lastSyncUs() const { return ctx_.last_sync_us; }
  TimeUs windowUs() const { return ctx_.sync_window_us; }
  // SYNC frames with a length other than 0x1019 implies (consumer).
  std::uint64_t wrongLength() const { return wrong_length_; }

 private:
  void emit(std::uint8_t counter, TimeUs now) {
    if (handler_) handler_(counter, now);
  }
  TimeUs monitorDeadline() const;
  NodeContext& ctx_;
  Handler handler_;
  TimeoutHook timeout_hook_;
  TimeUs timeout_us_ = 0;  // consumer monitoring (0: off)
  TimeUs last_rx_us_ = kNever;
  bool timed_out_ = false;
  std::uint64_t wrong_length_ = 0;
  std::uint32_t cob_id_ = 0x80;
  bool subscribed_ = false;
  bool producer_ = false;
  TimeUs period_us_ = 0;
  std::uint8_t overflow_ = 0;
  std::uint8_t counter_ = 0;
  TimeUs next_us_ = kNever;
  std::uint64_t produced_ = 0;
  std::uint64_t consumed_ = 0;
};

}  // namespace pamc::canopen
