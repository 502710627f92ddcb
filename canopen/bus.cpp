#include "canopen/bus.hpp"

#include <algorithm>
#include <stdexcept>

namespace pamc::canopen {

bool VirtualBus::Port::sendUntil(const Frame& frame, TimeUs deadline) { return bus_.enqueue(frame, this, deadline); }

VirtualBus::VirtualBus(TimeUs start_us, std::size_t queue_capacity)
    : now_(start_us), ring_(queue_capacity == 0 ? 1 : queue_capacity) {}

VirtualBus::Port& VirtualBus::addPort(BusClient* client) {
  ports_.push_back(std::unique_ptr<Port>(new Port(*this)));
  ports_.back()->setClient(client);
  if (bitrate_ > 0) {
    ports_.back()->queue_.resize(port_queue_);
    ports_.back()->deadline_.resize(port_queue_);
  }
  return *ports_.back();
}

void VirtualBus::setBitrate(std::uint32_t bits_per_second, std::size_t port_queue) {
  bitrate_ = bits_per_second;
  port_queue_ = port_queue == 0 ? 1 : port_queue;
  for (const auto& p : ports_) {
    p->queue_.assign(bitrate_ > 0 ? port_queue_ : 0, Frame{});
    p->deadline_.assign(bitrate_ > 0 ? port_queue_ : 0, kNever);
    p->head_ = p->count_ = 0;
  }
}

TimeUs VirtualBus::frameTimeUs(const Frame& f) const {
  if (bitrate_ == 0) return 0;
  // Error frames: 6 flag bits + 8 delimiter bits + 3 intermission.
  const std::uint64_t raw = f.error() ? 17 : (f.extended() ? 67u : 47u) + 8u * (f.remote() ? 0u : f.len);
  const std::uint64_t bits = raw + (raw + 9) / 10;  // stuff bits, about 10 %
  return static_cast<TimeUs>((bits * 1000000 + bitrate_ - 1) / bitrate_);
}

bool VirtualBus::enqueue(const Frame& frame, Port* sender, TimeUs deadline) {
  if (bitrate_ > 0) {
    if (sender->count_ == sender->queue_.size()) {
      ++sender->dropped_;
      ++dropped_;
      return false;
    }
    sender->queue_[(sender->head_ + sender->count_) % sender->queue_.size()] = frame;
    sender->deadline_[(sender->head_ + sender->count_) % sender->queue_.size()] = deadline;
    ++sender->count_;
    return true;
  }
  if (count_ == ring_.size()) {
    ++dropped_;
    return false;
  }
  ring_[(head_ + count_) % ring_.size()] = Queued{frame, sender};
  ++count_;
  return true;
}

void VirtualBus::deliver(const Frame& frame, const Port* sender) {
  ++delivered_;
  for (const Tap& tap : taps_) tap(frame, now_);
  // Like SocketCAN without CAN_RAW_RECV_OWN_MSGS: the sender does not see its own frame.
  for (const auto& p : ports_) {
    if (p.get() != sender && p->client_ != nullptr) p->client_->onFrame(frame, now_);
  }
}

namespace {
// CAN arbitration order: the base identifier first, a standard frame before an extended one with the
// same base identifier, a data frame before a remote frame. Error frames are not arbitrated (first).
std::uint32_t arbitrationKey(const Frame& f) {
  if (f.error()) return 0;
  const std::uint32_t base = f.extended() ? (f.id >> 18) & 0x7FF : f.id & 0x7FF;
  const std::uint32_t ext = f.extended() ? f.id & 0x3FFFF : 0;
  return 1 + ((base << 20) | (f.extended() ? 1u << 19 : 0u) | (ext << 1) | (f.remote() ? 1u : 0u));
}
}  // namespace

void VirtualBus::flushTimed() {
  for (;;) {
    if (in_flight_) {
      if (wire_done_ > now_) return;
      in_flight_ = false;
      deliver(wire_.frame, wire_.sender);
      continue;
    }
    Port* winner = nullptr;
    std::uint32_t best = 0;
    for (const auto& p : ports_) {
      // Frames past their deadline leave the queue unsent.
      while (p->count_ > 0 && p->deadline_[p->head_] < now_) {
        p->head_ = (p->head_ + 1) % p->queue_.size();
        --p->count_;
        ++p->expired_;
      }
      if (p->count_ == 0) continue;
      const std::uint32_t key = arbitrationKey(p->queue_[p->head_]);
      if (winner == nullptr || key < best) {
        winner = p.get();
        best = key;
      }
    }
    if (winner == nullptr) return;
    wire_ = Queued{winner->queue_[winner->head_], winner};
    winner->head_ = (winner->head_ + 1) % winner->queue_.size();
    --winner->count_;
    ++winner->sent_;
    const TimeUs d = std::max<TimeUs>(frameTimeUs(wire_.frame), 1);
    wire_done_ = now_ + d;
    busy_total_us_ += d;
    in_flight_ = true;
  }
}

void VirtualBus::flush() {
  if (bitrate_ > 0) return flushTimed();
  while (count_ > 0) {
    Queued q = ring_[head_];
    head_ = (head_ + 1) % ring_.size();
    --count_;
    deliver(q.frame, q.sender);
  }
}

void VirtualBus::advanceClients() {
  flush();  // frames whose time is up arrive before the clients' timers at the same instant
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
    TimeUs next = in_flight_ ? wire_done_ : kNever;
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
