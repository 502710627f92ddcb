#include "rig/bus_fault_rig.hpp"

#include "nodes/process_data.hpp"

#include <malloc.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>

#include "canopen/bus.hpp"
#include "canopen/eds.hpp"
#include "canopen/node.hpp"
#include "nodes/emulator_node.hpp"
#include "plant/plant.hpp"

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

// ---- Soak ------------------------------------------------------------------------------------------

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

}  // namespace

SoakResult runSoak(const SoakOptions& o, const std::function<void(const SoakInterval&)>& on_interval,
                   const std::function<void(double)>& on_progress) {
  SoakResult res;
#ifdef PAMC_SOAK_ASAN
  res.asan = true;
#endif
  const auto wall_start = std::chrono::steady_clock::now();
  const std::vector<BusFault> catalogue = o.faults.empty() ? allBusFaults() : o.faults;
  FaultRigOptions fo;
  fo.od_dir = o.od_dir;
  fo.kind = o.kind;
  fo.kp = o.kp;
  fo.ki = o.ki;
  fo.kc = o.kc;
  fo.seed = o.seed;
  auto rigp = std::make_unique<Rig>(BusFault::None, fo, true);
  Rig& r = *rigp;
  std::mt19937_64 rng(o.seed ^ 0x5DEECE66Dull);

  const double P = 1.0 / r.traj.freq_hz;  // trajectory period: the tracking windows
  const auto per_window = static_cast<std::uint64_t>(std::llround(P / 1e-3));
  const auto total_us = static_cast<TimeUs>(std::llround(o.hours * 3600e6));
  const auto report_us = std::max<TimeUs>(kPeriod, static_cast<TimeUs>(std::llround(o.report_s * 1e6)) / kPeriod * kPeriod);
  const auto gap_min = static_cast<TimeUs>(std::llround(o.gap_min_s * 1e6));
  const auto gap_max = std::max(gap_min, static_cast<TimeUs>(std::llround(o.gap_max_s * 1e6)));
  // Everything the soak itself keeps is allocated here, so that the heap in use shows the rig only.
  res.intervals.reserve(static_cast<std::size_t>(total_us / report_us) + 2);
  std::array<SoakFaultStat, 64> by_fault{};
  auto step_hist = std::make_unique<Histogram>();  // wall time per 1 ms step, in 0.1 us bins
  constexpr std::size_t kMaxFailures = 50;
  auto failure_text = std::make_unique<std::array<std::array<char, 320>, kMaxFailures>>();  // no allocation on a failure
  std::size_t failures_kept = 0;
  auto fail = [&](const char* fmt, auto... args) {
    ++res.failure_count;
    if (failures_kept >= kMaxFailures) return;
    char* b = (*failure_text)[failures_kept++].data();
    const int n = std::snprintf(b, 320, "%8.3f h: ", static_cast<double>(r.bus.now()) / 3600e6);
    std::snprintf(b + n, 320 - static_cast<std::size_t>(n), fmt, args...);
  };

  enum class St { Warmup, Idle, Injected, Clearing, Settling, Checking };
  St st = St::Warmup;
  BusFault cur = BusFault::None;
  TimeUs t_end = 0, t_clear = 0, next_inj = canopen::kNever, last_fault_us = 0;
  std::uint64_t episodes0 = 0;
  double settle_until = 0, resume_s = 0;
  long check_w = -1;
  // The trajectory period being accumulated.
  long w_idx = -1;
  double w_sum = 0;
  std::uint64_t w_n = 0;
  bool w_dirty = false, w_fault = false;
  double base_sum = 0;
  int base_n = 0;
  std::uint64_t not_back = 0;  // control not back within resume_limit_s

  SoakInterval iv;
  double clean_sum = 0;
  const auto& stats = r.ctrl->stats();
  std::uint64_t cycles0 = 0, missed0 = 0, syncs0 = 0, safe0 = 0, samples0 = 0, emcy0 = 0, dropped0 = 0;
  double cpu0 = cpuSeconds();
  auto wall0 = std::chrono::steady_clock::now();
  double heap_ref = -1, rss_ref = -1;

  auto schedule = [&](TimeUs now) {
    next_inj = now + std::uniform_int_distribution<TimeUs>(gap_min, gap_max)(rng);
  };
  auto finishWindow = [&](TimeUs now) {
    if (w_idx < 0 || w_n == 0) return;
    const double rm = std::sqrt(w_sum / static_cast<double>(w_n));
    const bool complete = w_n == per_window;
    if (st == St::Checking && w_idx == check_w) {
      auto& fs = by_fault[static_cast<std::size_t>(cur)];
      ++fs.checked, ++iv.checked, ++res.checked;
      const double ratio = res.baseline_rmse > 0 ? rm / res.baseline_rmse : 0.0;
      fs.worst_ratio = std::max(fs.worst_ratio, ratio);
      iv.worst_ratio = std::max(iv.worst_ratio, ratio);
      const bool ok = complete && !w_fault && rm <= res.baseline_rmse * (1.0 + o.tolerance) + 0.005;
      if (ok) {
        ++fs.back, ++iv.back, ++res.back;
      } else {
        fail("%s: tracking not back to normal: RMSE %.4f mm over %llu cycles%s (baseline %.4f mm)",
             busFaultName(cur), rm, static_cast<unsigned long long>(w_n), w_fault ? ", fault during the check" : "",
             res.baseline_rmse);
      }
      st = St::Idle;
      schedule(now);
      return;
    }
    if (w_dirty || !complete) return;
    if (st == St::Warmup) {
      if (static_cast<double>(w_idx) * P >= o.warmup_s && base_n < o.baseline_periods) {
        base_sum += rm;
        if (++base_n == o.baseline_periods) res.baseline_rmse = base_sum / base_n;
      }
      return;
    }
    clean_sum += rm;
    iv.clean_rmse_max = std::max(iv.clean_rmse_max, rm);
    ++iv.clean_periods;
    // Between faults the tracking must stay at its level, not just come back for the check.
    if (rm > res.baseline_rmse * (1.0 + o.tolerance) + 0.005) {
      ++iv.clean_bad;
      fail("tracking left its normal level without a fault: RMSE %.4f mm in the period from t = %.0f s (baseline "
           "%.4f mm; last fault %s)",
           rm, static_cast<double>(w_idx) * P, res.baseline_rmse, busFaultName(cur));
    }
  };
  auto onRecord = [&](const CycleRecord& rec, TimeUs now) {
    const long w = static_cast<long>(std::floor(rec.t / P + 1e-9));
    if (w != w_idx) {
      finishWindow(now);
      w_idx = w;
      w_sum = 0;
      w_n = 0;
      w_dirty = w_fault = false;
    }
    const double e = r.traj.at(rec.t) - rec.y;
    w_sum += e * e;
    ++w_n;
    if (rec.fault != 0) w_fault = w_dirty = true;
    if (!(st == St::Warmup || st == St::Idle || st == St::Checking)) w_dirty = true;
    if (st == St::Settling && rec.t + 1e-9 >= settle_until) {
      check_w = static_cast<long>(std::ceil(settle_until / P - 1e-9));
      st = St::Checking;
    }
  };
  auto closeInterval = [&](TimeUs now) {
    const auto& fc = r.ctrl->faultCounters();
    iv.index = static_cast<int>(res.intervals.size());
    iv.end_h = static_cast<double>(now) / 3600e6;
    iv.cycles = stats.cycles - cycles0;
    iv.missed_syncs = stats.missed_syncs - missed0;
    iv.syncs = r.sync->sent - syncs0;
    iv.safe_cycles = fc.safe_cycles - safe0;
    iv.samples_missing = fc.samples_missing - samples0;
    iv.emcy = r.emcy_frames - emcy0;
    iv.ring_dropped = r.ctrl->records().dropped() - dropped0;
    iv.clean_rmse_mean = iv.clean_periods ? clean_sum / static_cast<double>(iv.clean_periods) : 0.0;
    const double heap = heapInUseBytes(), rss = rssBytes();
    iv.heap_mb = heap / 1048576.0;
    iv.rss_mb = rss / 1048576.0;
    const double cpu = cpuSeconds();
    const auto wall = std::chrono::steady_clock::now();
    const double periods = static_cast<double>(report_us) / kPeriod;
    iv.cpu_us_per_cycle = (cpu - cpu0) * 1e6 / periods;
    iv.wall_s = std::chrono::duration<double>(wall - wall0).count();
    iv.step_us_p99 = step_hist->quantile(0.99) / 10.0;
    iv.step_us_max = step_hist->max() / 10.0;
    if (heap_ref < 0) heap_ref = heap, rss_ref = rss;
    res.heap_growth_bytes = heap - heap_ref;
    res.rss_growth_mb = (rss - rss_ref) / 1048576.0;
    res.intervals.push_back(iv);
    if (on_interval) on_interval(res.intervals.back());
    cycles0 = stats.cycles, missed0 = stats.missed_syncs, syncs0 = r.sync->sent, safe0 = fc.safe_cycles;
    samples0 = fc.samples_missing, emcy0 = r.emcy_frames, dropped0 = r.ctrl->records().dropped();
    cpu0 = cpuSeconds();
    wall0 = std::chrono::steady_clock::now();
    step_hist->reset();
    iv = SoakInterval{};
    clean_sum = 0;
  };

  std::uint64_t last_cycles = stats.cycles;
  TimeUs next_report = std::min(report_us, total_us);
  CycleRecord rec;
  while (r.bus.now() < total_us) {
    const TimeUs now0 = r.bus.now();
    TimeUs target = (now0 / kPeriod + 1) * kPeriod;
    if (st == St::Idle && next_inj < target) target = next_inj;
    if (st == St::Injected && t_end < target) target = t_end;
    target = std::min(target, next_report);
    const auto s0 = std::chrono::steady_clock::now();
    r.bus.advanceTo(target);
    const TimeUs now = r.bus.now();
    while (r.ctrl->records().pop(rec)) onRecord(rec, now);
    const bool tick = now % kPeriod == 0;
    if (tick) {
      step_hist->add(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - s0).count() * 10.0);
      // Outside faults every SYNC period runs exactly one control cycle.
      const std::uint64_t c = stats.cycles;
      const bool clean = st == St::Idle || st == St::Settling || st == St::Checking || (st == St::Warmup && now > 10 * kPeriod);
      if (clean && c - last_cycles != 1) {
        ++iv.lost_clean;
        fail("%llu control cycles in the SYNC period ending at %.3f s (expected 1, no fault active)",
             static_cast<unsigned long long>(c - last_cycles), static_cast<double>(now) * 1e-6);
      }
      last_cycles = c;
      if (on_progress && now % 60'000'000 == 0) on_progress(static_cast<double>(now) * 1e-6);
    }
    if (r.ctrl->fault() != Fault::None) last_fault_us = now;
    switch (st) {
      case St::Warmup:
        if (base_n >= o.baseline_periods) {
          st = St::Idle;
          schedule(now);
        }
        break;
      case St::Idle:
        if (now >= next_inj) {
          cur = catalogue[std::uniform_int_distribution<std::size_t>(0, catalogue.size() - 1)(rng)];
          episodes0 = r.ctrl->faultCounters().episodes;
          t_end = now + std::max<TimeUs>(1, static_cast<TimeUs>(std::llround(faultSeconds(cur) * 1e6)));
          begin(r, cur);
          auto& fs = by_fault[static_cast<std::size_t>(cur)];
          fs.fault = cur;
          ++fs.injected, ++iv.faults, ++res.faults;
          st = St::Injected;
        }
        break;
      case St::Injected:
        if (now >= t_end) {
          end(r, cur);
          t_clear = now;
          st = St::Clearing;
        }
        break;
      case St::Clearing: {
        const bool back = r.ctrl->fault() == Fault::None && r.ctrl->running();
        const bool timeout = now > t_clear + static_cast<TimeUs>(o.resume_limit_s * 1e6);
        if ((back && now >= t_clear + 100'000) || timeout) {
          auto& fs = by_fault[static_cast<std::size_t>(cur)];
          if (r.ctrl->faultCounters().episodes != episodes0) ++fs.reacted, ++iv.reacted, ++res.reacted;
          resume_s = last_fault_us > t_clear ? static_cast<double>(last_fault_us - t_clear) * 1e-6 : 0.0;
          fs.max_resume_s = std::max(fs.max_resume_s, resume_s);
          if (timeout && !back) ++not_back;
          if (timeout && !back)
            fail("%s: control not back %.0f s after the fault ended (%s)", busFaultName(cur), o.resume_limit_s,
                 toString(r.ctrl->fault()));
          settle_until = r.ctrl->runTime() + o.settle_s;
          st = St::Settling;
        }
        break;
      }
      case St::Settling:
      case St::Checking: break;
    }
    if (now >= next_report) {
      closeInterval(now);
      next_report = std::min(next_report + report_us, total_us);
    }
  }
  // Verdicts.
  const auto& ivs = res.intervals;
  std::uint64_t lost = 0, dropped = 0, clean_bad = 0;
  for (const auto& i : ivs) lost += i.lost_clean, dropped += i.ring_dropped, clean_bad += i.clean_bad;
  res.cycle_ok = lost == 0 && dropped == 0;
  res.tracking_ok = res.baseline_rmse > 0 && res.back == res.checked && not_back == 0 && clean_bad == 0;
  res.memory_ok = res.heap_growth_bytes <= o.heap_growth_limit;
  if (ivs.size() >= 3) {
    const std::size_t third = ivs.size() / 3;
    double a = 0, b = 0;
    for (std::size_t i = 0; i < third; ++i) a += ivs[i].cpu_us_per_cycle, b += ivs[ivs.size() - 1 - i].cpu_us_per_cycle;
    res.cpu_drift = a > 0 ? b / a : 0.0;
    res.timing_ok = res.cpu_drift <= o.cpu_drift_limit;
  }
  for (BusFault f : allBusFaults())
    if (by_fault[static_cast<std::size_t>(f)].injected) res.per_fault.push_back(by_fault[static_cast<std::size_t>(f)]);
  for (std::size_t i = 0; i < failures_kept; ++i) res.failures.emplace_back((*failure_text)[i].data());
  rigp.reset();
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return res;
}

std::string soakIntervalHeader() {
  return "| h | cycles | SYNC gaps | lost outside faults | ring drops | faults (safe state) | back to normal | "
         "worst RMSE / baseline | between faults: RMSE mean / max [mm] (periods above) | EMCY | heap [MB] | RSS [MB] | CPU [us/cycle] | "
         "step p99 / max [us] |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
}

std::string soakIntervalLine(const SoakInterval& i) {
  char b[512];
  std::snprintf(b, sizeof b,
                "| %.2f | %llu | %llu | %llu | %llu | %llu (%llu) | %llu/%llu | %.3f | %.4f / %.4f (%llu) | %llu | %.3f | %.1f | "
                "%.2f | %.1f / %.0f |\n",
                i.end_h, static_cast<unsigned long long>(i.cycles), static_cast<unsigned long long>(i.missed_syncs),
                static_cast<unsigned long long>(i.lost_clean), static_cast<unsigned long long>(i.ring_dropped),
                static_cast<unsigned long long>(i.faults), static_cast<unsigned long long>(i.reacted),
                static_cast<unsigned long long>(i.back), static_cast<unsigned long long>(i.checked), i.worst_ratio,
                i.clean_rmse_mean, i.clean_rmse_max, static_cast<unsigned long long>(i.clean_bad),
                static_cast<unsigned long long>(i.emcy), i.heap_mb, i.rss_mb,
                i.cpu_us_per_cycle, i.step_us_p99, i.step_us_max);
  return b;
}

std::string soakReport(const SoakOptions& o, const SoakResult& r, bool intervals) {
  std::string s;
  if (intervals) {
    s += soakIntervalHeader();
    for (const auto& i : r.intervals) s += soakIntervalLine(i);
  }
  char b[600];
  s += "\n| fault | injected | safe state | back to normal | worst RMSE / baseline | control back after (max) |\n"
       "|---|---|---|---|---|---|\n";
  for (const auto& f : r.per_fault) {
    std::snprintf(b, sizeof b, "| %s | %llu | %llu | %llu/%llu | %.3f | %.3f s |\n", busFaultName(f.fault),
                  static_cast<unsigned long long>(f.injected), static_cast<unsigned long long>(f.reacted),
                  static_cast<unsigned long long>(f.back), static_cast<unsigned long long>(f.checked), f.worst_ratio,
                  f.max_resume_s);
    s += b;
  }
  const double heap0 = r.intervals.empty() ? 0.0 : r.intervals.front().heap_mb;
  const double heap1 = r.intervals.empty() ? 0.0 : r.intervals.back().heap_mb;
  const double rss0 = r.intervals.empty() ? 0.0 : r.intervals.front().rss_mb;
  const double rss1 = r.intervals.empty() ? 0.0 : r.intervals.back().rss_mb;
  std::snprintf(b, sizeof b,
                "\n%.2f h simulated (%s, seed %llu) in %.0f s wall time; baseline tracking RMSE %.4f mm (%d periods "
                "before the first fault), tolerance %.0f %% + 0.005 mm\n",
                o.hours, control::toString(o.kind), static_cast<unsigned long long>(o.seed), r.wall_s, r.baseline_rmse,
                o.baseline_periods, o.tolerance * 100.0);
  s += b;
  std::snprintf(b, sizeof b,
                "memory: heap in use (%s) %.3f MB after the first report, %.3f MB at the end: %+.0f bytes (limit %.0f); "
                "RSS %.1f -> %.1f MB: %s\n",
                r.asan ? "AddressSanitizer allocator" : "mallinfo2", heap0, heap1, r.heap_growth_bytes,
                o.heap_growth_limit, rss0, rss1, r.memory_ok ? "ok" : "FAILED");
  s += b;
  std::uint64_t lost = 0, dropped = 0, cycles = 0, gaps = 0;
  for (const auto& i : r.intervals) lost += i.lost_clean, dropped += i.ring_dropped, cycles += i.cycles, gaps += i.missed_syncs;
  std::snprintf(b, sizeof b,
                "cycle: %llu control cycles, %llu SYNC gaps (all during SYNC faults), %llu periods outside faults "
                "without exactly one cycle, %llu records lost; CPU per cycle last third / first third %.2f (limit "
                "%.2f): %s\n",
                static_cast<unsigned long long>(cycles), static_cast<unsigned long long>(gaps),
                static_cast<unsigned long long>(lost), static_cast<unsigned long long>(dropped), r.cpu_drift,
                o.cpu_drift_limit, r.cycle_ok && r.timing_ok ? "ok" : "FAILED");
  s += b;
  std::uint64_t clean = 0, clean_bad = 0;
  for (const auto& i : r.intervals) clean += i.clean_periods, clean_bad += i.clean_bad;
  std::snprintf(b, sizeof b,
                "faults: %llu injected, %llu put the controller in its safe state, tracking back to normal after "
                "%llu of %llu checked; %llu of %llu trajectory periods between faults above the tolerance: %s\n",
                static_cast<unsigned long long>(r.faults), static_cast<unsigned long long>(r.reacted),
                static_cast<unsigned long long>(r.back), static_cast<unsigned long long>(r.checked),
                static_cast<unsigned long long>(clean_bad), static_cast<unsigned long long>(clean),
                r.tracking_ok ? "ok" : "FAILED");
  s += b;
  if (r.failure_count) {
    std::snprintf(b, sizeof b, "%llu failures%s:\n", static_cast<unsigned long long>(r.failure_count),
                  r.failure_count > r.failures.size() ? " (the first 50)" : "");
    s += b;
    for (const auto& f : r.failures) s += "  " + f + "\n";
  }
  s += r.passed() ? "verdict: PASS\n" : "verdict: FAIL\n";
  return s;
}

}  // namespace pamc::nodes
