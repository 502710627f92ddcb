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
class VirtualBus {
 public:
  class Port : public Transport {
   public:
    bool send(const Frame& frame) override;
    // The client receives frames sent by the other ports and is advanced by the bus; may be null.
    void setClient(BusClient* client) { client_ = client; }
    BusClient* client() const { return client_; }

   private:
    friend class VirtualBus;
    explicit Port(VirtualBus& bus) : bus_(bus) {}
    VirtualBus& bus_;
    BusClient* client_ = nullptr;
  };

  // Observer of every frame on the bus (in delivery order) with its virtual time.
  using Tap = std::function<void(const Frame& frame, TimeUs now)>;

  explicit VirtualBus(TimeUs start_us = 0, std::size_t queue_capacity = 4096);

  // Ports live as long as the bus. A port without client can still inject frames (a test tool).
  Port& addPort(BusClient* client = nullptr);
  void addTap(Tap tap) { taps_.push_back(std::move(tap)); }

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
  bool enqueue(const Frame& frame, const Port* sender);
  void advanceClients();

  TimeUs now_;
  std::vector<std::unique_ptr<Port>> ports_;
  std::vector<Tap> taps_;
  std::vector<Queued> ring_;  // fixed capacity, allocated once
  std::size_t head_ = 0;
  std::size_t count_ = 0;
  std::uint64_t delivered_ = 0;
  std::uint64_t dropped_ = 0;
};

}  // namespace pamc::canopen
