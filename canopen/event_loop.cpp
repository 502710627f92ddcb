#include "canopen/event_loop.hpp"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdint>
#include <system_error>

namespace pamc::canopen {

namespace {
constexpr TimeUs kTxRetryUs = 200;  // about two frames at 1 Mbit/s
[[noreturn]] void fail(const char* what) { throw std::system_error(errno, std::generic_category(), what); }
}  // namespace

EventLoop::EventLoop(SocketCanTransport& can, BusClient& client) : can_(can), client_(client) {
  timer_fd_ = ::timerfd_create(CLOCK_MONOTONIC, TFD_NONBLOCK | TFD_CLOEXEC);
  if (timer_fd_ < 0) fail("timerfd_create");
  wake_fd_ = ::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  if (wake_fd_ < 0) {
    ::close(timer_fd_);
    fail("eventfd");
  }
}

EventLoop::~EventLoop() {
  ::close(timer_fd_);
  ::close(wake_fd_);
}

void EventLoop::stop() {
  std::uint64_t one = 1;
  [[maybe_unused]] ssize_t n = ::write(wake_fd_, &one, sizeof one);
}

void EventLoop::run() { loop(kNever); }

void EventLoop::runFor(TimeUs duration_us) { loop(monotonicNowUs() + duration_us); }

void EventLoop::loop(TimeUs end_us) {
  for (;;) {
    TimeUs now = std::max(monotonicNowUs(), last_now_);
    last_now_ = now;
    client_.advance(now);
    if (now >= end_us) return;

    // Absolute expiry: the timer fires at the deadline itself, so wake-up jitter never accumulates.
    TimeUs deadline = std::min(client_.nextDeadline(), end_us);
    // ENOBUFS comes from the interface queue, which poll() does not see: POLLOUT can be ready while
    // writes still fail. After a failed retry wait a little instead of spinning on POLLOUT.
    bool want_pollout = can_.hasPendingTx() && now >= retry_tx_us_;
    if (can_.hasPendingTx() && !want_pollout) deadline = std::min(deadline, retry_tx_us_);
    itimerspec its{};
    if (deadline != kNever) {
      TimeUs at = std::max<TimeUs>(deadline, 1);
      its.it_value.tv_sec = static_cast<time_t>(at / 1000000);
      its.it_value.tv_nsec = static_cast<long>((at % 1000000) * 1000);
    }
    if (::timerfd_settime(timer_fd_, TFD_TIMER_ABSTIME, &its, nullptr) < 0) fail("timerfd_settime");

    pollfd fds[3] = {
        {can_.fd(), static_cast<short>(POLLIN | (want_pollout ? POLLOUT : 0)), 0},
        {timer_fd_, POLLIN, 0},
        {wake_fd_, POLLIN, 0},
    };
    int r = ::poll(fds, 3, -1);
    if (r < 0) {
      if (errno == EINTR) continue;
      fail("poll");
    }
    if ((fds[0].revents & POLLNVAL) != 0) {
      errno = EBADF;
      fail("CAN socket closed");
    }
    if ((fds[0].revents & (POLLIN | POLLERR)) != 0) {
      TimeUs mono_now = monotonicNowUs();
      TimeUs real_now = realtimeNowUs();
      Frame f;
      TimeUs stamp_us = 0;
      bool any = false;
      while (can_.receive(f, stamp_us)) {
        any = true;
        // Kernel timestamps are wall-clock; map them onto the monotonic timeline, never backwards.
        TimeUs t = std::clamp(mono_now - (real_now - stamp_us), last_now_, std::max(mono_now, last_now_));
        last_now_ = t;
        client_.onFrame(f, t);
      }
      if (!any && (fds[0].revents & POLLERR) != 0) {
        int err = 0;
        socklen_t len = sizeof err;
        ::getsockopt(can_.fd(), SOL_SOCKET, SO_ERROR, &err, &len);
        if (err == ENETDOWN || err == ENODEV) {
          errno = err;
          fail("CAN interface went down");
        }
      }
    }
    if ((fds[0].revents & POLLOUT) != 0 && !can_.flush()) retry_tx_us_ = monotonicNowUs() + kTxRetryUs;
    if ((fds[1].revents & POLLIN) != 0) {
      std::uint64_t expirations = 0;
      [[maybe_unused]] ssize_t n = ::read(timer_fd_, &expirations, sizeof expirations);
    }
    if ((fds[2].revents & POLLIN) != 0) {
      std::uint64_t v = 0;
      [[maybe_unused]] ssize_t n = ::read(wake_fd_, &v, sizeof v);
      return;
    }
  }
}

}  // namespace pamc::canopen
