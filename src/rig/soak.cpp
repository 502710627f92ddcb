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

namespace pamc::rig {

using namespace detail;
using namespace nodes;

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

// The soak's times: from its options and the trajectory's period.
struct SoakTiming {
  double P;                  // trajectory period: the tracking windows
  std::uint64_t per_window;  // control cycles in one
  TimeUs total_us, report_us, gap_min, gap_max;
};

SoakTiming soakTiming(const SoakOptions& o, double P) {
  SoakTiming t{};
  t.P = P;
  t.per_window = static_cast<std::uint64_t>(std::llround(P / 1e-3));
  t.total_us = static_cast<TimeUs>(std::llround(o.hours * 3600e6));
  t.report_us = std::max<TimeUs>(kPeriod, static_cast<TimeUs>(std::llround(o.report_s * 1e6)) / kPeriod * kPeriod);
  t.gap_min = static_cast<TimeUs>(std::llround(o.gap_min_s * 1e6));
  t.gap_max = std::max(t.gap_min, static_cast<TimeUs>(std::llround(o.gap_max_s * 1e6)));
  return t;
}

// The text of the first kMax failures, in buffers allocated up front: a failure allocates nothing.
class FailureLog {
 public:
  static constexpr std::size_t kMax = 50;
  FailureLog() : text_(std::make_unique<std::array<std::array<char, 320>, kMax>>()) {}
  void add(double at_h, const char* fmt, std::va_list args) __attribute__((format(printf, 3, 0)));
  void copyTo(std::vector<std::string>& out) const {
    for (std::size_t i = 0; i < kept_; ++i) out.emplace_back((*text_)[i].data());
  }

 private:
  std::unique_ptr<std::array<std::array<char, 320>, kMax>> text_;
  std::size_t kept_ = 0;
};

void FailureLog::add(double at_h, const char* fmt, std::va_list args) {
  if (kept_ >= kMax) return;
  char* b = (*text_)[kept_++].data();
  const int n = std::snprintf(b, 320, "%8.3f h: ", at_h);
  std::vsnprintf(b + n, 320 - static_cast<std::size_t>(n), fmt, args);
}

// One fault from its injection to its check, and when the next one is due.
struct Episode {
  BusFault fault = BusFault::None;
  TimeUs t_end = 0, t_clear = 0, next_inj = canopen::kNever;
  TimeUs last_fault_us = 0;     // the last step the controller was in a fault
  std::uint64_t episodes0 = 0;  // the controller's fault episodes at the injection
  double settle_until = 0;
  bool settled = false;  // a record at or after settle_until came in
  long check_w = -1;
  bool check_done = false;  // the check period closed and was judged
};

// The trajectory period being accumulated.
struct Window {
  long idx = -1;
  double sum = 0;
  std::uint64_t n = 0;
  bool dirty = false, fault = false;
};

// What the run is held against: the no-fault tracking baseline (the sum of its periods' RMSE so far)
// and the memory at the first report (-1: none yet).
struct References {
  double base_sum = 0;
  int base_n = 0;
  double heap = -1, rss = -1;
};

// The rig's counters at the start of a report interval: the interval reports their differences.
struct CounterMarks {
  std::uint64_t cycles = 0, missed = 0, syncs = 0, safe = 0, samples = 0, emcy = 0, dropped = 0;
  double cpu = 0;
  std::chrono::steady_clock::time_point wall;
};

// The report interval being accumulated.
struct ReportInterval {
  SoakInterval iv;
  double clean_sum = 0;
  CounterMarks start;
  std::unique_ptr<Histogram> step_hist;  // wall time per 1 ms step, in 0.1 us bins
  TimeUs next = 0;                       // when it ends
};

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
  void judgeCheck(double rm, bool complete);
  void countCycle(TimeUs now);
  CounterMarks marks() const;
  void closeInterval(TimeUs now);
  void measureUsage(SoakInterval::Usage& u);
  SoakResult finish();
  void fail(const char* fmt, ...) __attribute__((format(printf, 2, 3)));
  SoakFaultStat& stat() { return by_fault_[static_cast<std::size_t>(ep_.fault)]; }

  const SoakOptions& o_;
  const std::function<void(const SoakInterval&)>& on_interval_;
  const std::function<void(double)>& on_progress_;
  const std::chrono::steady_clock::time_point wall_start_ = std::chrono::steady_clock::now();
  SoakResult res_;
  std::vector<BusFault> catalogue_;
  std::unique_ptr<Rig> rig_;
  Rig& r_;
  std::mt19937_64 rng_;
  const SoakTiming tm_;
  std::array<SoakFaultStat, 64> by_fault_{};
  FailureLog failures_;

  State state_ = State::Warmup;
  Episode ep_;
  Window win_;
  References refs_;
  std::uint64_t not_back_ = 0;  // control not back within resume_limit_s
  std::uint64_t last_cycles_ = 0;
  ReportInterval rep_;
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
      tm_(soakTiming(o, 1.0 / r_.traj.freq_hz)) {
#ifdef PAMC_SOAK_ASAN
  res_.asan = true;
#endif
  res_.intervals.reserve(static_cast<std::size_t>(tm_.total_us / tm_.report_us) + 2);
  rep_.step_hist = std::make_unique<Histogram>();
  rep_.start = marks();
  last_cycles_ = r_.ctrl->stats().cycles;
  rep_.next = std::min(tm_.report_us, tm_.total_us);
}

SoakResult Soak::run() {
  while (r_.bus.now() < tm_.total_us) step();
  return finish();
}

void Soak::step() {
  const TimeUs now0 = r_.bus.now();
  const TimeUs target = std::min({(now0 / kPeriod + 1) * kPeriod, wakeUp(), rep_.next});
  const auto s0 = std::chrono::steady_clock::now();
  r_.bus.advanceTo(target);
  const TimeUs now = r_.bus.now();
  CycleRecord rec;
  while (r_.ctrl->records().pop(rec)) takeRecord(rec);
  if (now % kPeriod == 0) {
    const double step_us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s0).count();
    rep_.step_hist->add(step_us * 10.0);
    countCycle(now);
  }
  if (r_.ctrl->fault() != Fault::None) ep_.last_fault_us = now;

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

  if (now >= rep_.next) {
    closeInterval(now);
    rep_.next = std::min(rep_.next + tm_.report_us, tm_.total_us);
  }
}

Soak::State Soak::warmup() const { return refs_.base_n >= o_.baseline_periods ? State::Idle : State::Warmup; }

Soak::State Soak::idle(TimeUs now) const { return now >= ep_.next_inj ? State::Injected : State::Idle; }

Soak::State Soak::injected(TimeUs now) const { return now >= ep_.t_end ? State::Clearing : State::Injected; }

// Waits for control to come back; then records whether the fault put the controller in its safe
// state and how long it took to resume.
Soak::State Soak::clearing(TimeUs now) {
  const bool back = r_.ctrl->fault() == Fault::None && r_.ctrl->running();
  const bool timeout = now > ep_.t_clear + static_cast<TimeUs>(o_.resume_limit_s * 1e6);
  if (!((back && now >= ep_.t_clear + 100'000) || timeout)) return State::Clearing;
  auto& fs = stat();
  if (r_.ctrl->faultCounters().episodes != ep_.episodes0) ++fs.reacted, ++rep_.iv.reacted, ++res_.reacted;
  const TimeUs since_clear = ep_.last_fault_us - ep_.t_clear;
  const double resume_s = since_clear > 0 ? static_cast<double>(since_clear) * 1e-6 : 0.0;
  fs.max_resume_s = std::max(fs.max_resume_s, resume_s);
  if (timeout && !back) {
    ++not_back_;
    fail("%s: control not back %.0f s after the fault ended (%s)", busFaultName(ep_.fault), o_.resume_limit_s,
         toString(r_.ctrl->fault()));
  }
  return State::Settling;
}

// Both leave on the cycle records (takeRecord): settling once trajectory time reaches settle_until,
// checking once the check period closed.
Soak::State Soak::settling() const { return ep_.settled ? State::Checking : State::Settling; }

Soak::State Soak::checking() const { return ep_.check_done ? State::Idle : State::Checking; }

void Soak::enter(State next, TimeUs now) {
  switch (next) {
    case State::Warmup: break;
    case State::Idle:  // the next injection after a random gap
      ep_.next_inj = now + std::uniform_int_distribution<TimeUs>(tm_.gap_min, tm_.gap_max)(rng_);
      break;
    case State::Injected: {
      ep_.fault = catalogue_[std::uniform_int_distribution<std::size_t>(0, catalogue_.size() - 1)(rng_)];
      ep_.episodes0 = r_.ctrl->faultCounters().episodes;
      ep_.t_end = now + std::max<TimeUs>(1, static_cast<TimeUs>(std::llround(faultSeconds(ep_.fault) * 1e6)));
      begin(r_, ep_.fault);
      auto& fs = stat();
      fs.fault = ep_.fault;
      ++fs.injected, ++rep_.iv.faults, ++res_.faults;
      break;
    }
    case State::Clearing:
      end(r_, ep_.fault);
      ep_.t_clear = now;
      break;
    case State::Settling:
      ep_.settle_until = r_.ctrl->runTime() + o_.settle_s;
      ep_.settled = false;
      break;
    case State::Checking:  // the first whole trajectory period after settling
      ep_.check_w = static_cast<long>(std::ceil(ep_.settle_until / tm_.P - 1e-9));
      ep_.check_done = false;
      break;
  }
  state_ = next;
}

TimeUs Soak::wakeUp() const {
  if (state_ == State::Idle) return ep_.next_inj;
  if (state_ == State::Injected) return ep_.t_end;
  return canopen::kNever;
}

// One control cycle into the trajectory period it belongs to; a period is clean if no fault was
// active and no fault was on the bus or being recovered from during it.
void Soak::takeRecord(const CycleRecord& rec) {
  const long w = static_cast<long>(std::floor(rec.t / tm_.P + 1e-9));
  if (w != win_.idx) {
    closeWindow();
    win_ = Window{};
    win_.idx = w;
  }
  const double e = r_.traj.at(rec.t) - rec.y;
  win_.sum += e * e;
  ++win_.n;
  if (rec.fault != 0) win_.fault = win_.dirty = true;
  if (!(state_ == State::Warmup || state_ == State::Idle || state_ == State::Checking)) win_.dirty = true;
  if (state_ == State::Settling && rec.t + 1e-9 >= ep_.settle_until) ep_.settled = true;
}

// A trajectory period ended: the check after a fault, a period of the baseline, or a clean period
// between faults.
void Soak::closeWindow() {
  if (win_.idx < 0 || win_.n == 0) return;
  const double rm = std::sqrt(win_.sum / static_cast<double>(win_.n));
  const bool complete = win_.n == tm_.per_window;
  if (state_ == State::Checking && win_.idx == ep_.check_w && !ep_.check_done) {
    judgeCheck(rm, complete);
    return;
  }
  if (win_.dirty || !complete) return;
  if (state_ == State::Warmup) {
    if (static_cast<double>(win_.idx) * tm_.P >= o_.warmup_s && refs_.base_n < o_.baseline_periods) {
      refs_.base_sum += rm;
      if (++refs_.base_n == o_.baseline_periods) res_.baseline_rmse = refs_.base_sum / refs_.base_n;
    }
    return;
  }
  rep_.clean_sum += rm;
  rep_.iv.clean.rmse_max = std::max(rep_.iv.clean.rmse_max, rm);
  ++rep_.iv.clean.periods;
  // Between faults the tracking must stay at its level, not just come back for the check.
  if (rm > res_.baseline_rmse * (1.0 + o_.tolerance) + 0.005) {
    ++rep_.iv.clean.bad;
    fail(
        "tracking left its normal level without a fault: RMSE %.4f mm in the period from t = %.0f s (baseline "
        "%.4f mm; last fault %s)",
        rm, static_cast<double>(win_.idx) * tm_.P, res_.baseline_rmse, busFaultName(ep_.fault));
  }
}

// The check period after a fault: tracking back to the baseline's level, without a fault during it.
void Soak::judgeCheck(double rm, bool complete) {
  auto& fs = stat();
  ++fs.checked, ++rep_.iv.checked, ++res_.checked;
  const double ratio = res_.baseline_rmse > 0 ? rm / res_.baseline_rmse : 0.0;
  fs.worst_ratio = std::max(fs.worst_ratio, ratio);
  rep_.iv.worst_ratio = std::max(rep_.iv.worst_ratio, ratio);
  const bool ok = complete && !win_.fault && rm <= res_.baseline_rmse * (1.0 + o_.tolerance) + 0.005;
  if (ok) {
    ++fs.back, ++rep_.iv.back, ++res_.back;
  } else {
    fail("%s: tracking not back to normal: RMSE %.4f mm over %llu cycles%s (baseline %.4f mm)", busFaultName(ep_.fault),
         rm, static_cast<unsigned long long>(win_.n), win_.fault ? ", fault during the check" : "", res_.baseline_rmse);
  }
  ep_.check_done = true;
}

// Outside faults every SYNC period runs exactly one control cycle.
void Soak::countCycle(TimeUs now) {
  const std::uint64_t c = r_.ctrl->stats().cycles;
  const bool clean = state_ == State::Idle || state_ == State::Settling || state_ == State::Checking ||
                     (state_ == State::Warmup && now > 10 * kPeriod);
  if (clean && c - last_cycles_ != 1) {
    ++rep_.iv.lost_clean;
    fail("%llu control cycles in the SYNC period ending at %.3f s (expected 1, no fault active)",
         static_cast<unsigned long long>(c - last_cycles_), static_cast<double>(now) * 1e-6);
  }
  last_cycles_ = c;
  if (on_progress_ && now % 60'000'000 == 0) on_progress_(static_cast<double>(now) * 1e-6);
}

CounterMarks Soak::marks() const {
  const auto& stats = r_.ctrl->stats();
  const auto& fc = r_.ctrl->faultCounters();
  CounterMarks m;
  m.cycles = stats.cycles, m.missed = stats.missed_syncs, m.syncs = r_.sync->sent, m.safe = fc.safe_cycles;
  m.samples = fc.samples_missing, m.emcy = r_.emcy_frames, m.dropped = r_.ctrl->records().dropped();
  m.cpu = cpuSeconds();
  m.wall = std::chrono::steady_clock::now();
  return m;
}

void Soak::closeInterval(TimeUs now) {
  const CounterMarks& s = rep_.start;
  const CounterMarks e = marks();
  SoakInterval& iv = rep_.iv;
  iv.index = static_cast<int>(res_.intervals.size());
  iv.end_h = static_cast<double>(now) / 3600e6;
  iv.cycles = e.cycles - s.cycles;
  iv.missed_syncs = e.missed - s.missed;
  iv.syncs = e.syncs - s.syncs;
  iv.safe_cycles = e.safe - s.safe;
  iv.samples_missing = e.samples - s.samples;
  iv.emcy = e.emcy - s.emcy;
  iv.ring_dropped = e.dropped - s.dropped;
  iv.clean.rmse_mean = iv.clean.periods ? rep_.clean_sum / static_cast<double>(iv.clean.periods) : 0.0;
  measureUsage(iv.usage);
  res_.intervals.push_back(iv);
  if (on_interval_) on_interval_(res_.intervals.back());
  rep_.start = marks();
  rep_.step_hist->reset();
  rep_.iv = SoakInterval{};
  rep_.clean_sum = 0;
}

// Memory at the end of the interval (and its growth since the first report), CPU and wall time over
// it, the step times.
void Soak::measureUsage(SoakInterval::Usage& u) {
  const double heap = heapInUseBytes(), rss = rssBytes();
  u.heap_mb = heap / 1048576.0;
  u.rss_mb = rss / 1048576.0;
  const double periods = static_cast<double>(tm_.report_us) / kPeriod;
  u.cpu_us_per_cycle = (cpuSeconds() - rep_.start.cpu) * 1e6 / periods;
  u.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - rep_.start.wall).count();
  u.step_us_p99 = rep_.step_hist->quantile(0.99) / 10.0;
  u.step_us_max = rep_.step_hist->max() / 10.0;
  if (refs_.heap < 0) refs_.heap = heap, refs_.rss = rss;
  res_.heap_growth_bytes = heap - refs_.heap;
  res_.rss_growth_mb = (rss - refs_.rss) / 1048576.0;
}

// The verdicts over the whole run.
SoakResult Soak::finish() {
  SoakResult& res = res_;
  const auto& ivs = res.intervals;
  std::uint64_t lost = 0, dropped = 0, clean_bad = 0;
  for (const auto& i : ivs) lost += i.lost_clean, dropped += i.ring_dropped, clean_bad += i.clean.bad;
  res.cycle_ok = lost == 0 && dropped == 0;
  res.tracking_ok = res.baseline_rmse > 0 && res.back == res.checked && not_back_ == 0 && clean_bad == 0;
  res.memory_ok = res.heap_growth_bytes <= o_.heap_growth_limit;
  if (ivs.size() >= 3) {
    const std::size_t third = ivs.size() / 3;
    double a = 0, b = 0;
    for (std::size_t i = 0; i < third; ++i)
      a += ivs[i].usage.cpu_us_per_cycle, b += ivs[ivs.size() - 1 - i].usage.cpu_us_per_cycle;
    res.cpu_drift = a > 0 ? b / a : 0.0;
    res.timing_ok = res.cpu_drift <= o_.cpu_drift_limit;
  }
  for (BusFault f : allBusFaults())
    if (by_fault_[static_cast<std::size_t>(f)].injected)
      res.per_fault.push_back(by_fault_[static_cast<std::size_t>(f)]);
  failures_.copyTo(res.failures);
  rig_.reset();
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start_).count();
  return std::move(res);
}

// Counts every failure, keeps the text of the first FailureLog::kMax.
void Soak::fail(const char* fmt, ...) {
  ++res_.failure_count;
  std::va_list args;
  va_start(args, fmt);
  failures_.add(static_cast<double>(r_.bus.now()) / 3600e6, fmt, args);
  va_end(args);
}

}  // namespace

SoakResult runSoak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval,
                   const std::function<void(double)>& on_progress) {
  return Soak(o, on_interval, on_progress).run();
}

}  // namespace pamc::rig
