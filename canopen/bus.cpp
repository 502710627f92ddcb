#include "canopen/bus.hpp"

#include <algorithm>
#include <stdexcept>

namespace pamc::canopen {

bool VirtualBus::Port::send(const Frame& frame) { return bus_.enqueue(frame, this); }

VirtualBus::VirtualBus(TimeUs start_us, std::size_t queue_capacity)
    : now_(start_us), ring_(queue_capacity == 0 ? 1 : queue_capacity) {}

VirtualBus::Port& VirtualBus::addPort(BusClient* client) {
  ports_.push_back(std::unique_ptr<Port>(new Port(*this)));
  ports_.back()->setClient(client);
  return *ports_.back();
}

bool VirtualBus::enqueue(const Frame& frame, const Port* sender) {
  if (count_ == ring_.size()) {
    ++dropped_;
    return false;
  }
  ring_[(head_ + count_) % ring_.size()] = Queued{frame, sender};
  ++count_;
  return true;
}

void VirtualBus::flush() {
  while (count_ > 0) {
    Queued q = ring_[head_];
    head_ = (head_ + 1) % ring_.size();
    --count_;
    ++delivered_;
    for (const Tap& tap : taps_) tap(q.frame, now_);
    // Like SocketCAN without CAN_RAW_RECV_OWN_MSGS: the sender does not see its own frame.
    for (const auto& p : ports_) {
      if (p.get() != q.sender && p->client_ != nullptr) p->client_->onFrame(q.frame, now_);
    }
  }
}

void VirtualBus::advanceClients() {
  for (const auto& p : ports_) {
    if (p->client_ != nullptr) p->client_->advance(now_);
  }
  flush();
}

void VirtualBus::advanceTo(TimeUs t) {
  flush();
  // A client whose deadline does not move after advance() would spin here; that is a bug, so stop loudly.
  int same_time_rounds = 0;
  for (;;) {
    TimeUs next = kNever;
    for (const auto& p : ports_) {
      if (p->client_ != nullptr) next = std::min(next, p->client_->nextDeadline());
    }
    if (next > t) break;
    if (next <= now_) {
      if (++same_time_rounds > 1000) throw std::logic_error("VirtualBus: a client deadline does not advance");
    } else {
      same_time_rounds = 0;
      now_ = next;
    }
    advanceClients();
  }
  if (t > now_) now_ = t;
  advanceClients();
}

}  // namespace pamc::canopen
