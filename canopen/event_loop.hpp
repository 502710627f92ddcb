// Real-time driver for a passive node on SocketCAN: poll() on the CAN socket, a timerfd armed at the
// node's next deadline (CLOCK_MONOTONIC), and an eventfd to stop. Kept apart from the core on purpose.
#pragma once

#include "canopen/bus.hpp"
#include "canopen/socketcan.hpp"

namespace pamc::canopen {

class EventLoop {
 public:
  // client is usually a Node built with `can` as its transport. Throws std::system_error.
  EventLoop(SocketCanTransport& can, BusClient& client);
  ~EventLoop();
  EventLoop(const EventLoop&) = delete;
  EventLoop& operator=(const EventLoop&) = delete;

  // Runs until stop(); the node sees monotonic time in microseconds. Throws std::system_error if the
  // socket fails for good (e.g. the interface disappears).
  void run();
  // Runs for duration_us, then returns (also returns early on stop()).
  void runFor(TimeUs duration_us);
  // Thread- and signal-safe.
  void stop();

 private:
  void loop(TimeUs end_us);
  SocketCanTransport& can_;
  BusClient& client_;
  int timer_fd_ = -1;
  int wake_fd_ = -1;
  TimeUs last_now_ = 0;
  TimeUs retry_tx_us_ = 0;  // earliest retry of queued frames after a failed flush
};

}  // namespace pamc::canopen
