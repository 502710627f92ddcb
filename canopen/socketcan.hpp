// SocketCAN raw transport (Linux): any can*/vcan* interface, receive timestamps (SO_TIMESTAMP),
// error frames, and a transmit queue that absorbs ENOBUFS/EAGAIN (retry on POLLOUT).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "canopen/bus.hpp"
#include "canopen/frame.hpp"

namespace pamc::canopen {

struct SocketCanOptions {
  // Error classes delivered as error frames (CAN_RAW_ERR_FILTER); default: all (CAN_ERR_MASK).
  std::uint32_t error_mask = 0x1FFFFFFF;
  // Also receive frames this socket sent (CAN_RAW_RECV_OWN_MSGS); CANopen nodes normally do not.
  bool receive_own = false;
  // Frames held while the kernel queue is full; beyond this send() reports a drop.
  std::size_t tx_queue_capacity = 256;
};

struct SocketCanStats {
  std::uint64_t rx_frames = 0;
  std::uint64_t tx_frames = 0;
  std::uint64_t tx_queued = 0;   // send() hit ENOBUFS/EAGAIN and queued the frame
  std::uint64_t tx_dropped = 0;  // queue full
  // Queued with a deadline (sendUntil) and dropped unsent: the deadline passed before the frame could be
  // written, or the queue was full and the room went to a frame without a deadline (see sendUntil).
  std::uint64_t tx_expired = 0;
  std::uint64_t tx_errors = 0;  // other write errors (e.g. ENETDOWN)
  std::uint64_t rx_errors = 0;  // read errors other than EAGAIN
  std::uint64_t error_frames = 0;
};

class SocketCanTransport : public Transport {
 public:
  // Sees every frame sent or received, with its wall-clock time (kernel timestamp on receive).
  using Tap = std::function<void(const Frame& frame, TimeUs unix_time_us, bool transmitted)>;

  // Opens a non-blocking raw socket bound to interface; throws std::system_error naming it.
  explicit SocketCanTransport(const std::string& interface, SocketCanOptions options = {});
  // Takes ownership of an already open datagram socket carrying struct can_frame records (made
  // non-blocking here). Lets tests run the transport and the event loop on a socketpair.
  static std::unique_ptr<SocketCanTransport> adopt(int fd, const std::string& name, SocketCanOptions options = {});
  ~SocketCanTransport() override;
  SocketCanTransport(const SocketCanTransport&) = delete;
  SocketCanTransport& operator=(const SocketCanTransport&) = delete;

  // Writes now, or queues behind earlier frames; false only if the queue is full or the write failed hard.
  // A frame without a deadline (EMCY, heartbeat, NMT, SDO) is never dropped while the queue holds a
  // frame with one: when the queue is full, frames past their deadline are removed first, then the
  // oldest frame that has a deadline gives up its place (counted in tx_expired). It goes out, in
  // order, once the kernel takes frames again.
  bool send(const Frame& frame) override { return sendUntil(frame, kNever); }
  // The same; a queued frame still waiting at deadline (monotonic us) is dropped, not written late.
  // (Frames the kernel has accepted cannot be recalled: this covers the queue behind ENOBUFS.)
  bool sendUntil(const Frame& frame, TimeUs deadline) override;
  // Retries queued frames (call when poll() reports POLLOUT); true when the queue is empty.
  bool flush();
  bool hasPendingTx() const { return queue_count_ > 0; }
  std::size_t queued() const override { return queue_count_; }
  std::uint64_t expiredCount() const override { return stats_.tx_expired; }
  // Reads one frame if available; unix_time_us is the kernel receive timestamp.
  bool receive(Frame& out, TimeUs& unix_time_us);

  int fd() const { return fd_; }
  const std::string& interface() const { return interface_; }
  const SocketCanStats& stats() const { return stats_; }
  void setTap(Tap tap) { tap_ = std::move(tap); }

 private:
  SocketCanTransport(int fd, const std::string& name, SocketCanOptions options);
  // 1: written, 0: would block (retry later), -1: hard error.
  int writeFrame(const Frame& frame);
  // Removes queued frames whose deadline is before now, wherever they are (the others keep their order).
  void purgeExpired(TimeUs now);
  // Removes the oldest queued frame that has a deadline; false if every queued frame has none.
  bool evictOldestWithDeadline();
  void removeAt(std::size_t i);  // i-th frame from the head

  std::string interface_;
  int fd_ = -1;
  SocketCanStats stats_;
  Tap tap_;
  std::vector<Frame> queue_;  // ring buffer, allocated once
  std::vector<TimeUs> deadline_;
  std::size_t queue_head_ = 0;
  std::size_t queue_count_ = 0;
};

// Wall clock in microseconds since the Unix epoch (for logs), and the monotonic clock nodes run on.
TimeUs realtimeNowUs();
TimeUs monotonicNowUs();

}  // namespace pamc::canopen
