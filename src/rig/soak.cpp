// The soak: one long run of the rig with random faults (fault_rig.hpp); its report is soak_report.cpp.
#include "rig/bus_fault_rig.hpp"

#include <malloc.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <functional>
#include <memory>
#include <random>
#include <vector>

#include "canopen/bus.hpp"

// Heap in use under AddressSanitizer comes from its allocator (mallinfo2 sees glibc's, which it replaces).
#if defined(__SANITIZE_ADDRESS__)
#define PAMC_SOAK_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define PAMC_SOAK_ASAN 1
#endif
#endif
#ifdef PAMC_SOAK_ASAN
// From <sanitizer/allocator_interface.h>, which GCC does not install everywhere; libasan provides it.
extern "C" std::size_t __sanitizer_get_current_allocated_bytes(void);
#endif

namespace pamc::nodes {

using namespace detail;

namespace {

double heapInUseBytes() {
#ifdef PAMC_SOAK_ASAN
  return static_cast<double>(__sanitizer_get_current_allocated_bytes());
#elif defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  const struct mallinfo2 mi = ::mallinfo2();
  return static_cast<double>(mi.uordblks + mi.hblkhd);  // in use: small blocks + mmapped ones
#else
  return 0.0;
#endif
}

double rssBytes() {
  long pages = 0, resident = 0;
  if (std::FILE* f = std::fopen("/proc/self/statm", "r")) {
    if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
    std::fclose(f);
  }
  return static_cast<double>(resident) * static_cast<double>(::sysconf(_SC_PAGESIZE));
}

double cpuSeconds() {
  timespec ts{};
  ::clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

// The soak as a state machine. step() advances the bus to the next event (the next 1 ms tick, or
// earlier for an injection, its end or a report), takes in the records of the cycles that ran, then
// does the work of the current state, which names the next state; enter() is the only place the state
// changes. Everything the soak keeps is allocated in the constructor, so that the heap in use shows
// the rig only.
class Soak {
 public:
  Soak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval,
       const std::function<void(double)>& on_progress);
  SoakResult run();

 private:
  enum class State {
    Warmup,    // no faults until the baseline is taken
    Idle,      // tracking between faults, until the next injection is due
    Injected,  // a fault on the bus for its duration
    Clearing,  // the fault cleared, until control is back (or resume_limit_s is over)
    Settling,  // control back, settle_s of trajectory time before the check
    Checking,  // the trajectory period checked against the baseline
  };

  void step();
  State warmup() const;
  State idle(TimeUs now) const;
  State injected(TimeUs now) const;
  State clearing(TimeUs now);
  State settling() const;
  State checking() const;
  void enter(State next, TimeUs now);

  TimeUs wakeUp() const;  // the time the current state waits for (canopen::kNever: none)
  void takeRecord(const CycleRecord& rec);
  void closeWindow();
  void countCycle(TimeUs now);
  void closeInterval(TimeUs now);
  SoakResult finish();
  void fail(const char* fmt, ...) __attribute__((format(printf, 2, 3)));
  SoakFaultStat& stat() { return by_fault_[static_cast<std::size_t>(cur_)]; }

  const SoakOptions& o_;
  const std::function<void(const SoakInterval&)>& on_interval_;
  const std::function<void(double)>& on_progress_;
  const std::chrono::steady_clock::time_point wall_start_ = std::chrono::steady_clock::now();
  SoakResult res_;
  std::vector<BusFault> catalogue_;
  std::unique_ptr<Rig> rig_;
  Rig& r_;
  std::mt19937_64 rng_;

  const double P_;                  // trajectory period: the tracking windows
  const std::uint64_t per_window_;  // control cycles in one
  const TimeUs total_us_, report_us_, gap_min_, gap_max_;

  std::array<SoakFaultStat, 64> by_fault_{};
  std::unique_ptr<Histogram> step_hist_;  // wall time per 1 ms step, in 0.1 us bins
  static constexpr std::size_t kMaxFailures = 50;
  std::unique_ptr<std::array<std::array<char, 320>, kMaxFailures>> failure_text_;  // no allocation on a failure
  std::size_t failures_kept_ = 0;

  State state_ = State::Warmup;
  BusFault cur_ = BusFault::None;
  TimeUs t_end_ = 0, t_clear_ = 0, next_inj_ = canopen::kNever, last_fault_us_ = 0;
  std::uint64_t episodes0_ = 0;
  double settle_until_ = 0;
  bool settled_ = false;     // a record at or after settle_until_ came in
  long check_w_ = -1;
  bool check_done_ = false;  // the check period closed and was judged
  // The trajectory period being accumulated.
  long w_idx_ = -1;
  double w_sum_ = 0;
  std::uint64_t w_n_ = 0;
  bool w_dirty_ = false, w_fault_ = false;
  double base_sum_ = 0;
  int base_n_ = 0;
  std::uint64_t not_back_ = 0;  // control not back within resume_limit_s

  // The report interval being accumulated, and the counters at its start.
  SoakInterval iv_;
  double clean_sum_ = 0;
  std::uint64_t cycles0_ = 0, missed0_ = 0, syncs0_ = 0, safe0_ = 0, samples0_ = 0, emcy0_ = 0, dropped0_ = 0;
  double cpu0_ = 0;
  std::chrono::steady_clock::time_point wall0_;
  double heap_ref_ = -1, rss_ref_ = -1;
  std::uint64_t last_cycles_ = 0;
  TimeUs next_report_ = 0;
};

FaultRigOptions rigOptions(const SoakOptions& o) {
  FaultRigOptions fo;
  fo.od_dir = o.od_dir;
  fo.kind = o.kind;
  fo.kp = o.kp;
  fo.ki = o.ki;
  fo.kc = o.kc;
  fo.seed = o.seed;
  return fo;
}

Soak::Soak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval,
           const std::function<void(double)>& on_progress)
    : o_(o),
      on_interval_(on_interval),
      on_progress_(on_progress),
      catalogue_(o.faults.empty() ? runningBusFaults() : o.faults),
      rig_(std::make_unique<Rig>(BusFault::None, rigOptions(o), true)),
      r_(*rig_),
      rng_(o.seed ^ 0x5DEECE66Dull),
      P_(1.0 / r_.traj.freq_hz),
      per_window_(static_cast<std::uint64_t>(std::llround(P_ / 1e-3))),
      total_us_(static_cast<TimeUs>(std::llround(o.hours * 3600e6))),
      report_us_(std::max<TimeUs>(kPeriod, static_cast<TimeUs>(std::llround(o.report_s * 1e6)) / kPeriod * kPeriod)),
      gap_min_(static_cast<TimeUs>(std::llround(o.gap_min_s * 1e6))),
      gap_max_(std::max(gap_min_, static_cast<TimeUs>(std::llround(o.gap_max_s * 1e6)))) {
#ifdef PAMC_SOAK_ASAN
  res_.asan = true;
#endif
  res_.intervals.reserve(static_cast<std::size_t>(total_us_ / report_us_) + 2);
  step_hist_ = std::make_unique<Histogram>();
  failure_text_ = std::make_unique<std::array<std::array<char, 320>, kMaxFailures>>();
  cycles0_ = r_.ctrl->stats().cycles;
  missed0_ = r_.ctrl->stats().missed_syncs;
  syncs0_ = r_.sync->sent;
  safe0_ = r_.ctrl->faultCounters().safe_cycles;
  samples0_ = r_.ctrl->faultCounters().samples_missing;
  emcy0_ = r_.emcy_frames;
  dropped0_ = r_.ctrl->records().dropped();
  cpu0_ = cpuSeconds();
  wall0_ = std::chrono::steady_clock::now();
  last_cycles_ = r_.ctrl->stats().cycles;
  next_report_ = std::min(report_us_, total_us_);
}

SoakResult Soak::run() {
  while (r_.bus.now() < total_us_) step();
  return finish();
}

void Soak::step() {
  const TimeUs now0 = r_.bus.now();
  const TimeUs target = std::min({(now0 / kPeriod + 1) * kPeriod, wakeUp(), next_report_});
  const auto s0 = std::chrono::steady_clock::now();
  r_.bus.advanceTo(target);
  const TimeUs now = r_.bus.now();
  CycleRecord rec;
  while (r_.ctrl->records().pop(rec)) takeRecord(rec);
  if (now % kPeriod == 0) {
    step_hist_->add(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s0).count() * 10.0);
    countCycle(now);
  }
  if (r_.ctrl->fault() != Fault::None) last_fault_us_ = now;

  State next = state_;
  switch (state_) {
    case State::Warmup: next = warmup(); break;
    case State::Idle: next = idle(now); break;
    case State::Injected: next = injected(now); break;
    case State::Clearing: next = clearing(now); break;
    case State::Settling: next = settling(); break;
    case State::Checking: next = checking(); break;
  }
  if (next != state_) enter(next, now);

  if (now >= next_report_) {
    closeInterval(now);
    next_report_ = std::min(next_report_ + report_us_, total_us_);
  }
}

Soak::State Soak::warmup() const { return base_n_ >= o_.baseline_periods ? State::Idle : State::Warmup; }

Soak::State Soak::idle(TimeUs now) const { return now >= next_inj_ ? State::Injected : State::Idle; }

Soak::State Soak::injected(TimeUs now) const { return now >= t_end_ ? State::Clearing : State::Injected; }

// Waits for control to come back; then records whether the fault put the controller in its safe
// state and how long it took to resume.
Soak::State Soak::clearing(TimeUs now) {
  const bool back = r_.ctrl->fault() == Fault::None && r_.ctrl->running();
  const bool timeout = now > t_clear_ + static_cast<TimeUs>(o_.resume_limit_s * 1e6);
  if (!((back && now >= t_clear_ + 100'000) || timeout)) return State::Clearing;
  auto& fs = stat();
  if (r_.ctrl->faultCounters().episodes != episodes0_) ++fs.reacted, ++iv_.reacted, ++res_.reacted;
  const double resume_s = last_fault_us_ > t_clear_ ? static_cast<double>(last_fault_us_ - t_clear_) * 1e-6 : 0.0;
  fs.max_resume_s = std::max(fs.max_resume_s, resume_s);
  if (timeout && !back) {
    ++not_back_;
    fail("%s: control not back %.0f s after the fault ended (%s)", busFaultName(cur_), o_.resume_limit_s,
         toString(r_.ctrl->fault()));
  }
  return State::Settling;
}

// Both leave on the cycle records (takeRecord): settling once trajectory time reaches settle_until_,
// checking once the check period closed.
Soak::State Soak::settling() const { return settled_ ? State::Checking : State::Settling; }

Soak::State Soak::checking() const { return check_done_ ? State::Idle : State::Checking; }

void Soak::enter(State next, TimeUs now) {
  switch (next) {
    case State::Warmup: break;
    case State::Idle:  // the next injection after a random gap
      next_inj_ = now + std::uniform_int_distribution<TimeUs>(gap_min_, gap_max_)(rng_);
      break;
    case State::Injected: {
      cur_ = catalogue_[std::uniform_int_distribution<std::size_t>(0, catalogue_.size() - 1)(rng_)];
      episodes0_ = r_.ctrl->faultCounters().episodes;
      t_end_ = now + std::max<TimeUs>(1, static_cast<TimeUs>(std::llround(faultSeconds(cur_) * 1e6)));
      begin(r_, cur_);
      auto& fs = stat();
      fs.fault = cur_;
      ++fs.injected, ++iv_.faults, ++res_.faults;
      break;
    }
    case State::Clearing:
      end(r_, cur_);
      t_clear_ = now;
      break;
    case State::Settling:
      settle_until_ = r_.ctrl->runTime() + o_.settle_s;
      settled_ = false;
      break;
    case State::Checking:  // the first whole trajectory period after settling
      check_w_ = static_cast<long>(std::ceil(settle_until_ / P_ - 1e-9));
      check_done_ = false;
      break;
  }
  state_ = next;
}

TimeUs Soak::wakeUp() const {
  if (state_ == State::Idle) return next_inj_;
  if (state_ == State::Injected) return t_end_;
  return canopen::kNever;
}

// One control cycle into the trajectory period it belongs to; a period is clean if no fault was
// active and no fault was on the bus or being recovered from during it.
void Soak::takeRecord(const CycleRecord& rec) {
  const long w = static_cast<long>(std::floor(rec.t / P_ + 1e-9));
  if (w != w_idx_) {
    closeWindow();
    w_idx_ = w;
    w_sum_ = 0;
    w_n_ = 0;
    w_dirty_ = w_fault_ = false;
  }
  const double e = r_.traj.at(rec.t) - rec.y;
  w_sum_ += e * e;
  ++w_n_;
  if (rec.fault != 0) w_fault_ = w_dirty_ = true;
  if (!(state_ == State::Warmup || state_ == State::Idle || state_ == State::Checking)) w_dirty_ = true;
  if (state_ == State::Settling && rec.t + 1e-9 >= settle_until_) settled_ = true;
}

// A trajectory period ended: the check after a fault, a period of the baseline, or a clean period
// between faults.
void Soak::closeWindow() {
  if (w_idx_ < 0 || w_n_ == 0) return;
  const double rm = std::sqrt(w_sum_ / static_cast<double>(w_n_));
  const bool complete = w_n_ == per_window_;
  if (state_ == State::Checking && w_idx_ == check_w_ && !check_done_) {
    auto& fs = stat();
    ++fs.checked, ++iv_.checked, ++res_.checked;
    const double ratio = res_.baseline_rmse > 0 ? rm / res_.baseline_rmse : 0.0;
    fs.worst_ratio = std::max(fs.worst_ratio, ratio);
    iv_.worst_ratio = std::max(iv_.worst_ratio, ratio);
    const bool ok = complete && !w_fault_ && rm <= res_.baseline_rmse * (1.0 + o_.tolerance) + 0.005;
    if (ok) {
      ++fs.back, ++iv_.back, ++res_.back;
    } else {
      fail("%s: tracking not back to normal: RMSE %.4f mm over %llu cycles%s (baseline %.4f mm)", busFaultName(cur_),
           rm, static_cast<unsigned long long>(w_n_), w_fault_ ? ", fault during the check" : "", res_.baseline_rmse);
    }
    check_done_ = true;
    return;
  }
  if (w_dirty_ || !complete) return;
  if (state_ == State::Warmup) {
    if (static_cast<double>(w_idx_) * P_ >= o_.warmup_s && base_n_ < o_.baseline_periods) {
      base_sum_ += rm;
      if (++base_n_ == o_.baseline_periods) res_.baseline_rmse = base_sum_ / base_n_;
    }
    return;
  }
  clean_sum_ += rm;
  iv_.clean_rmse_max = std::max(iv_.clean_rmse_max, rm);
  ++iv_.clean_periods;
  // Between faults the tracking must stay at its level, not just come back for the check.
  if (rm > res_.baseline_rmse * (1.0 + o_.tolerance) + 0.005) {
    ++iv_.clean_bad;
    fail("tracking left its normal level without a fault: RMSE %.4f mm in the period from t = %.0f s (baseline "
         "%.4f mm; last fault %s)",
         rm, static_cast<double>(w_idx_) * P_, res_.baseline_rmse, busFaultName(cur_));
  }
}

// Outside faults every SYNC period runs exactly one control cycle.
void Soak::countCycle(TimeUs now) {
  const std::uint64_t c = r_.ctrl->stats().cycles;
  const bool clean = state_ == State::Idle || state_ == State::Settling || state_ == State::Checking ||
                     (state_ == State::Warmup && now > 10 * kPeriod);
  if (clean && c - last_cycles_ != 1) {
    ++iv_.lost_clean;
    fail("%llu control cycles in the SYNC period ending at %.3f s (expected 1, no fault active)",
         static_cast<unsigned long long>(c - last_cycles_), static_cast<double>(now) * 1e-6);
  }
  last_cycles_ = c;
  if (on_progress_ && now % 60'000'000 == 0) on_progress_(static_cast<double>(now) * 1e-6);
}

void Soak::closeInterval(TimeUs now) {
  const auto& stats = r_.ctrl->stats();
  const auto& fc = r_.ctrl->faultCounters();
  SoakInterval& iv = iv_;
  iv.index = static_cast<int>(res_.intervals.size());
  iv.end_h = static_cast<double>(now) / 3600e6;
  iv.cycles = stats.cycles - cycles0_;
  iv.missed_syncs = stats.missed_syncs - missed0_;
  iv.syncs = r_.sync->sent - syncs0_;
  iv.safe_cycles = fc.safe_cycles - safe0_;
  iv.samples_missing = fc.samples_missing - samples0_;
  iv.emcy = r_.emcy_frames - emcy0_;
  iv.ring_dropped = r_.ctrl->records().dropped() - dropped0_;
  iv.clean_rmse_mean = iv.clean_periods ? clean_sum_ / static_cast<double>(iv.clean_periods) : 0.0;
  const double heap = heapInUseBytes(), rss = rssBytes();
  iv.heap_mb = heap / 1048576.0;
  iv.rss_mb = rss / 1048576.0;
  const double cpu = cpuSeconds();
  const auto wall = std::chrono::steady_clock::now();
  const double periods = static_cast<double>(report_us_) / kPeriod;
  iv.cpu_us_per_cycle = (cpu - cpu0_) * 1e6 / periods;
  iv.wall_s = std::chrono::duration<double>(wall - wall0_).count();
  iv.step_us_p99 = step_hist_->quantile(0.99) / 10.0;
  iv.step_us_max = step_hist_->max() / 10.0;
  if (heap_ref_ < 0) heap_ref_ = heap, rss_ref_ = rss;
  res_.heap_growth_bytes = heap - heap_ref_;
  res_.rss_growth_mb = (rss - rss_ref_) / 1048576.0;
  res_.intervals.push_back(iv);
  if (on_interval_) on_interval_(res_.intervals.back());
  cycles0_ = stats.cycles, missed0_ = stats.missed_syncs, syncs0_ = r_.sync->sent, safe0_ = fc.safe_cycles;
  samples0_ = fc.samples_missing, emcy0_ = r_.emcy_frames, dropped0_ = r_.ctrl->records().dropped();
  cpu0_ = cpuSeconds();
  wall0_ = std::chrono::steady_clock::now();
  step_hist_->reset();
  iv_ = SoakInterval{};
  clean_sum_ = 0;
}

// The verdicts over the whole run.
SoakResult Soak::finish() {
  SoakResult& res = res_;
  const auto& ivs = res.intervals;
  std::uint64_t lost = 0, dropped = 0, clean_bad = 0;
  for (const auto& i : ivs) lost += i.lost_clean, dropped += i.ring_dropped, clean_bad += i.clean_bad;
  res.cycle_ok = lost == 0 && dropped == 0;
  res.tracking_ok = res.baseline_rmse > 0 && res.back == res.checked && not_back_ == 0 && clean_bad == 0;
  res.memory_ok = res.heap_growth_bytes <= o_.heap_growth_limit;
  if (ivs.size() >= 3) {
    const std::size_t third = ivs.size() / 3;
    double a = 0, b = 0;
    for (std::size_t i = 0; i < third; ++i) a += ivs[i].cpu_us_per_cycle, b += ivs[ivs.size() - 1 - i].cpu_us_per_cycle;
    res.cpu_drift = a > 0 ? b / a : 0.0;
    res.timing_ok = res.cpu_drift <= o_.cpu_drift_limit;
  }
  for (BusFault f : allBusFaults())
    if (by_fault_[static_cast<std::size_t>(f)].injected) res.per_fault.push_back(by_fault_[static_cast<std::size_t>(f)]);
  for (std::size_t i = 0; i < failures_kept_; ++i) res.failures.emplace_back((*failure_text_)[i].data());
  rig_.reset();
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
  return std::move(res);
}

// Counts every failure, keeps the text of the first kMaxFailures (in buffers allocated up front).
void Soak::fail(const char* fmt, ...) {
  ++res_.failure_count;
  if (failures_kept_ >= kMaxFailures) return;
  char* b = (*failure_text_)[failures_kept_++].data();
  const int n = std::snprintf(b, 320, "%8.3f h: ", static_cast<double>(r_.bus.now()) / 3600e6);
  std::va_list args;
  va_start(args, fmt);
  std::vsnprintf(b + n, 320 - static_cast<std::size_t>(n), fmt, args);
  va_end(args);
}

}  // namespace

SoakResult runSoak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval,
                   const std::function<void(double)>& on_progress) {
  return Soak(o, on_interval, on_progress).run();
}

}  // namespace pamc::nodes
