#include "canopen/socketcan.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <system_error>

namespace pamc::canopen {

namespace {

[[noreturn]] void fail(const std::string& what, const std::string& interface) {
  throw std::system_error(errno, std::generic_category(), "SocketCAN " + interface + ": " + what);
}

TimeUs clockUs(clockid_t id) {
  timespec ts{};
  clock_gettime(id, &ts);
  return static_cast<TimeUs>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

}  // namespace

TimeUs realtimeNowUs() { return clockUs(CLOCK_REALTIME); }
TimeUs monotonicNowUs() { return clockUs(CLOCK_MONOTONIC); }

SocketCanTransport::SocketCanTransport(const std::string& interface, SocketCanOptions options)
    : interface_(interface),
      queue_(options.tx_queue_capacity == 0 ? 1 : options.tx_queue_capacity),
      deadline_(queue_.size(), kNever) {
  if (interface.empty() || interface.size() >= IFNAMSIZ) {
    errno = EINVAL;
    fail("invalid interface name", interface);
  }
  fd_ = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd_ < 0) fail("socket(PF_CAN) failed", interface);
  try {
    ifreq ifr{};
    std::strncpy(ifr.ifr_name, interface.c_str(), IFNAMSIZ - 1);
    if (::ioctl(fd_, SIOCGIFINDEX, &ifr) < 0) fail("no such interface", interface);
    can_err_mask_t err_mask = options.error_mask & CAN_ERR_MASK;
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &err_mask, sizeof err_mask) < 0) {
      fail("CAN_RAW_ERR_FILTER", interface);
    }
    int own = options.receive_own ? 1 : 0;
    if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own) < 0) {
      fail("CAN_RAW_RECV_OWN_MSGS", interface);
    }
    int on = 1;
    if (::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on) < 0) fail("SO_TIMESTAMP", interface);
    sockaddr_can addr{};
    addr.can_family = AF_CAN;
    addr.can_ifindex = ifr.ifr_ifindex;
    if (::bind(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) < 0) fail("bind failed", interface);
  } catch (...) {
    ::close(fd_);
    fd_ = -1;
    throw;
  }
}

SocketCanTransport::SocketCanTransport(int fd, const std::string& name, SocketCanOptions options)
    : interface_(name),
      fd_(fd),
      queue_(options.tx_queue_capacity == 0 ? 1 : options.tx_queue_capacity),
      deadline_(queue_.size(), kNever) {
  int flags = ::fcntl(fd_, F_GETFL, 0);
  if (flags < 0 || ::fcntl(fd_, F_SETFL, flags | O_NONBLOCK) < 0) {
    ::close(fd_);
    fd_ = -1;
    fail("cannot make the socket non-blocking", name);
  }
  int on = 1;
  ::setsockopt(fd_, SOL_SOCKET, SO_TIMESTAMP, &on, sizeof on);  // best effort: receive() falls back to now
}

std::unique_ptr<SocketCanTransport> SocketCanTransport::adopt(int fd, const std::string& name,
                                                              SocketCanOptions options) {
  return std::unique_ptr<SocketCanTransport>(new SocketCanTransport(fd, name, options));
}

SocketCanTransport::~SocketCanTransport() {
  if (fd_ >= 0) ::close(fd_);
}

int SocketCanTransport::writeFrame(const Frame& frame) {
  can_frame cf{};
  cf.can_id = frame.extended() ? ((frame.id & CAN_EFF_MASK) | CAN_EFF_FLAG) : (frame.id & CAN_SFF_MASK);
  if (frame.remote()) cf.can_id |= CAN_RTR_FLAG;
  cf.can_dlc = frame.len > 8 ? 8 : frame.len;
  std::memcpy(cf.data, frame.data, cf.can_dlc);
  ssize_t n = ::write(fd_, &cf, sizeof cf);
  if (n == static_cast<ssize_t>(sizeof cf)) {
    ++stats_.tx_frames;
    if (tap_) tap_(frame, realtimeNowUs(), true);
    return 1;
  }
  // ENOBUFS: the interface queue is full (SocketCAN does not block even on blocking sockets).
  if (n < 0 && (errno == ENOBUFS || errno == EAGAIN || errno == EWOULDBLOCK)) return 0;
  ++stats_.tx_errors;
  return -1;
}

bool SocketCanTransport::sendUntil(const Frame& frame, TimeUs deadline) {
  // Frames already waiting go first so the order on the bus is the order of send() calls.
  if (queue_count_ == 0) {
    int r = writeFrame(frame);
    if (r != 0) return r > 0;
  }
  if (queue_count_ == queue_.size()) {
    // Stale frames behind a head the kernel keeps refusing must not take the room of fresh ones.
    purgeExpired(monotonicNowUs());
    // A frame without a deadline (an EMCY above all) is worth more than a SYNC or synchronous PDO,
    // which is of no use late anyway: the oldest of those makes room.
    if (queue_count_ == queue_.size() && deadline == kNever && evictOldestWithDeadline()) ++stats_.tx_expired;
    if (queue_count_ == queue_.size()) {
      ++stats_.tx_dropped;
      return false;
    }
  }
  queue_[(queue_head_ + queue_count_) % queue_.size()] = frame;
  deadline_[(queue_head_ + queue_count_) % queue_.size()] = deadline;
  ++queue_count_;
  ++stats_.tx_queued;
  return true;
}

void SocketCanTransport::removeAt(std::size_t i) {
  const std::size_t cap = queue_.size();
  // Shift the frames before it up by one: the queue keeps its order.
  for (std::size_t k = i; k > 0; --k) {
    queue_[(queue_head_ + k) % cap] = queue_[(queue_head_ + k - 1) % cap];
    deadline_[(queue_head_ + k) % cap] = deadline_[(queue_head_ + k - 1) % cap];
  }
  queue_head_ = (queue_head_ + 1) % cap;
  --queue_count_;
}

void SocketCanTransport::purgeExpired(TimeUs now) {
  const std::size_t cap = queue_.size();
  std::size_t kept = 0;
  for (std::size_t i = 0; i < queue_count_; ++i) {
    const std::size_t from = (queue_head_ + i) % cap;
    if (deadline_[from] < now) {
      ++stats_.tx_expired;
      continue;
    }
    const std::size_t to = (queue_head_ + kept) % cap;
    if (to != from) {
      queue_[to] = queue_[from];
      deadline_[to] = deadline_[from];
    }
    ++kept;
  }
  queue_count_ = kept;
}

bool SocketCanTransport::evictOldestWithDeadline() {
  for (std::size_t i = 0; i < queue_count_; ++i) {
    if (deadline_[(queue_head_ + i) % queue_.size()] != kNever) {
      removeAt(i);
      return true;
    }
  }
  return false;
}

bool SocketCanTransport::flush() {
  const TimeUs now = queue_count_ > 0 ? monotonicNowUs() : 0;
  // Not only at the head: a frame without a deadline at the head may wait long behind a full
  // interface queue, and the expired frames behind it would fill the queue meanwhile.
  if (queue_count_ > 0) purgeExpired(now);
  while (queue_count_ > 0) {
    if (deadline_[queue_head_] < now) {  // too late to be of use
      ++stats_.tx_expired;
      queue_head_ = (queue_head_ + 1) % queue_.size();
      --queue_count_;
      continue;
    }
    int r = writeFrame(queue_[queue_head_]);
    if (r == 0) return false;  // still full: wait for the next POLLOUT
    // A hard error drops the frame (counted) rather than blocking the queue forever.
    queue_head_ = (queue_head_ + 1) % queue_.size();
    --queue_count_;
  }
  return true;
}

bool SocketCanTransport::receive(Frame& out, TimeUs& unix_time_us) {
  can_frame cf{};
  iovec iov{&cf, sizeof cf};
  alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timeval))];
  msghdr msg{};
  msg.msg_iov = &iov;
  msg.msg_iovlen = 1;
  msg.msg_control = control;
  msg.msg_controllen = sizeof control;
  for (;;) {
    ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EINTR) continue;
      if (errno != EAGAIN && errno != EWOULDBLOCK) ++stats_.rx_errors;
      return false;
    }
    if (n != static_cast<ssize_t>(sizeof cf)) {  // not a classic CAN frame (e.g. CAN FD): skip it
      ++stats_.rx_errors;
      msg.msg_controllen = sizeof control;
      continue;
    }
    break;
  }
  unix_time_us = 0;
  for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
    if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SCM_TIMESTAMP) {
      timeval tv{};
      std::memcpy(&tv, CMSG_DATA(c), sizeof tv);
      unix_time_us = static_cast<TimeUs>(tv.tv_sec) * 1000000 + tv.tv_usec;
    }
  }
  if (unix_time_us == 0) unix_time_us = realtimeNowUs();

  out = Frame{};
  if ((cf.can_id & CAN_ERR_FLAG) != 0) {
    out.flags = kFrameError;
    out.id = cf.can_id & CAN_ERR_MASK;
    ++stats_.error_frames;
  } else if ((cf.can_id & CAN_EFF_FLAG) != 0) {
    out.flags = kFrameExtended;
    out.id = cf.can_id & CAN_EFF_MASK;
  } else {
    out.id = cf.can_id & CAN_SFF_MASK;
  }
  if ((cf.can_id & CAN_RTR_FLAG) != 0) out.flags |= kFrameRemote;
  out.len = cf.can_dlc > 8 ? 8 : cf.can_dlc;
  std::memcpy(out.data, cf.data, out.len);
  ++stats_.rx_frames;
  if (tap_) tap_(out, unix_time_us, false);
  return true;
}

}  // namespace pamc::canopen
