// Transport interface, the passive-node interface, and an in-process CAN bus with a manual clock.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "canopen/frame.hpp"

namespace pamc::canopen {

// Where a node's frames go. send() never blocks and never throws; false means the frame was dropped.
class Transport {
 public:
  virtual ~Transport() = default;
  virtual bool send(const Frame& frame) = 0;
  // A frame that is worthless after deadline (a SYNC or synchronous PDO after its synchronous window,
  // CiA 301 7.2.2.5): a transport that has to queue it drops it instead of sending it late.
  virtual bool sendUntil(const Frame& frame, TimeUs deadline) {
    (void)deadline;
    return send(frame);
  }
  // Frames accepted by send() that are still waiting to go out (a backlog the node can watch).
  virtual std::size_t queued() const { return 0; }
  // Frames accepted by sendUntil() and dropped at their deadline, unsent.
  virtual std::uint64_t expiredCount() const { return 0; }
};

// A passive CAN participant: it reacts to frames and to time, and never reads a clock itself.
class BusClient {
 public:
  virtual ~BusClient() = default;
  virtual void onFrame(const Frame& frame, TimeUs now) = 0;
  // Runs every timer due at or before now.
  virtual void advance(TimeUs now) = 0;
  // Earliest time advance() has work to do, or kNever.
  virtual TimeUs nextDeadline() const = 0;
};

// In-process bus in virtual time: frames are delivered in send order to every other port at the
// current virtual time; time moves only in advanceTo()/advanceBy(), deadline by deadline, so runs are
// deterministic and as fast as the CPU allows.
//
// With setBitrate() the bus also has timing: every port queues its frames (FIFO, like a CAN
// controller's transmit queue), a frame occupies the bus for its bit time (47 + 8 * DLC bits for a
// standard frame, 67 + 8 * DLC extended, plus 10 % for stuff bits) and is delivered when it has been
// sent; whenever the bus is idle the queue heads arbitrate and the lowest identifier wins, as on CAN.
// A port whose queue is full refuses the frame (send() returns false, the node counts tx_dropped); a
// frame sent with a deadline (sendUntil) that has not won the bus by then is dropped (expired).
class VirtualBus {
 public:
  class Port : public Transport {
   public:
    bool send(const Frame& frame) override { return sendUntil(frame, kNever); }
    bool sendUntil(const Frame& frame, TimeUs deadline) override;
    // The client receives frames sent by the other ports and is advanced by the bus; may be null.
    void setClient(BusClient* client) { client_ = client; }
    BusClient* client() const { return client_; }
    // With a bitrate: frames waiting in this port's queue, and frames refused because it was full.
    std::size_t queued() const override { return count_; }
    std::uint64_t dropped() const { return dropped_; }
    std::uint64_t expired() const { return expired_; }  // dropped at their deadline, never sent
    std::uint64_t expiredCount() const override { return expired_; }
    std::uint64_t sent() const { return sent_; }

   private:
    friend class VirtualBus;
    explicit Port(VirtualBus& bus) : bus_(bus) {}
    VirtualBus& bus_;
    BusClient* client_ = nullptr;
    std::vector<Frame> queue_;  // with a bitrate: ring, allocated once
    std::vector<TimeUs> deadline_;
    std::size_t head_ = 0;
    std::size_t count_ = 0;
    std::uint64_t dropped_ = 0;
    std::uint64_t expired_ = 0;
    std::uint64_t sent_ = 0;
  };

  // Observer of every frame on the bus (in delivery order) with its virtual time.
  using Tap = std::function<void(const Frame& frame, TimeUs now)>;

  explicit VirtualBus(TimeUs start_us = 0, std::size_t queue_capacity = 4096);

  // Ports live as long as the bus. A port without client can still inject frames (a test tool).
  Port& addPort(BusClient* client = nullptr);
  void addTap(Tap tap) { taps_.push_back(std::move(tap)); }

  // Bus timing (see above); 0 (the default) is the ideal bus. Call before frames are sent;
  // port_queue is each port's transmit queue in frames (SocketCanTransport's default is 256).
  void setBitrate(std::uint32_t bits_per_second, std::size_t port_queue = 256);
  std::uint32_t bitrate() const { return bitrate_; }
  // Time a frame occupies the bus at the configured bitrate (0 on the ideal bus).
  TimeUs frameTimeUs(const Frame& frame) const;
  // Virtual time the bus has been busy sending frames (with a bitrate).
  TimeUs busyUs() const { return busy_total_us_; }

  TimeUs now() const { return now_; }
  // Delivers queued frames (and whatever they trigger) without moving time.
  void flush();
  // Moves time to t, stopping at every client deadline on the way; t earlier than now is ignored.
  void advanceTo(TimeUs t);
  void advanceBy(TimeUs dt) { advanceTo(now_ + dt); }

  std::uint64_t framesDelivered() const { return delivered_; }
  std::uint64_t framesDropped() const { return dropped_; }  // queue overflow

 private:
  struct Queued {
    Frame frame;
    const Port* sender;
  };
  bool enqueue(const Frame& frame, Port* sender, TimeUs deadline);
  void deliver(const Frame& frame, const Port* sender);
  void advanceClients();
  // With a bitrate: delivers the frame on the wire once its time is up and starts the next one.
  void flushTimed();

  TimeUs now_;
  std::vector<std::unique_ptr<Port>> ports_;
  std::vector<Tap> taps_;
  std::vector<Queued> ring_;  // fixed capacity, allocated once
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::uint64_t delivered_ = 0;
  std::uint64_t dropped_ = 0;
  std::uint32_t bitrate_ = 0;
  std::size_t port_queue_ = 256;
  bool in_flight_ = false;
  Queued wire_{};         // the frame on the bus
  TimeUs wire_done_ = 0;  // when it has been sent
  TimeUs busy_total_us_ = 0;
};

}  // namespace pamc::canopen
