// Cycle statistics of a SYNC-driven node without allocation in the cycle: SYNC-to-setpoint latency,
// SYNC period jitter and overruns in fixed 1 us histograms, and a lock-free ring of cycle records
// that another thread drains and formats (no text in the 1 kHz path).
#pragma once

#include <array>
#include <atomic>
#include <algorithm>
#include <cmath>
#include <cstdint>

namespace pamc::nodes {

class Histogram {
 public:
  static constexpr int kBins = 20000;  // 1 us bins up to 20 ms; beyond goes in the last bin
  void add(double us) noexcept {
    const int b = us < 0 ? 0 : us >= kBins - 1 ? kBins - 1 : static_cast<int>(us);
    ++bins_[static_cast<size_t>(b)];
    ++n_;
    if (us > max_) max_ = us;
    sum_ += us;
  }
  std::uint64_t count() const noexcept { return n_; }
  double max() const noexcept { return max_; }
  double mean() const noexcept { return n_ ? sum_ / static_cast<double>(n_) : 0.0; }
  double quantile(double q) const noexcept {
    if (!n_) return 0.0;
    const auto target = static_cast<std::uint64_t>(std::ceil(q * static_cast<double>(n_)));
    std::uint64_t acc = 0;
    for (int b = 0; b < kBins; ++b) {
      acc += bins_[static_cast<size_t>(b)];
      if (acc >= target) return std::min(b + 0.5, max_);
    }
    return kBins;
  }
  void reset() noexcept {
    bins_.fill(0);
    n_ = 0;
    max_ = 0;
    sum_ = 0;
  }

 private:
  std::array<std::uint32_t, kBins> bins_{};
  std::uint64_t n_ = 0;
  double max_ = 0, sum_ = 0;
};

struct CycleStats {
  Histogram latency_us;  // SYNC received -> setpoint handed to the bus
  Histogram jitter_us;   // |SYNC interval - period|
  std::uint64_t cycles = 0;
  std::uint64_t overruns = 0;      // latency longer than the period, or SYNCs missed
  std::uint64_t missed_syncs = 0;  // gaps in the SYNC counter / intervals of more than 1.5 periods
};

struct CycleRecord {
  std::uint32_t k = 0;
  double t = 0, yd = 0, y = 0, u = 0, u_n = 0, u_c = 0, y_hat = 0;
  std::uint8_t fault = 0;
  float latency_us = 0;
  double p = NAN;            // the valve's pressure feedback latched with y [bar]; NaN where the rig maps none
  std::uint8_t channel = 0;  // the node's channel (0-based)
};

// Single producer (the SYNC callback), single consumer (a logger thread).
template <class T, size_t N>
class SpscRing {
  static_assert((N & (N - 1)) == 0, "N must be a power of two");

 public:
  bool push(const T& v) noexcept {
    const size_t h = head_.load(std::memory_order_relaxed);
    if (h - tail_.load(std::memory_order_acquire) >= N) {
      ++dropped_;
      return false;
    }
    buf_[h & (N - 1)] = v;
    head_.store(h + 1, std::memory_order_release);
    return true;
  }
  bool pop(T& v) noexcept {
    const size_t t = tail_.load(std::memory_order_relaxed);
    if (t == head_.load(std::memory_order_acquire)) return false;
    v = buf_[t & (N - 1)];
    tail_.store(t + 1, std::memory_order_release);
    return true;
  }
  std::uint64_t dropped() const noexcept { return dropped_; }

 private:
  std::array<T, N> buf_{};
  std::atomic<size_t> head_{0}, tail_{0};
  std::uint64_t dropped_ = 0;
};

}  // namespace pamc::nodes
