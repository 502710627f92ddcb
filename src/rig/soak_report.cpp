// The soak's report: one Markdown line per report interval, the per-fault table, the summary of
// memory, cycle and tracking, the failures and the verdict.
#include <cstdio>
#include <string>

#include "rig/fault_rig.hpp"

namespace pamc::rig {

using namespace nodes;

std::string soakIntervalHeader() {
  return "| h | cycles | SYNC gaps | lost outside faults | ring drops | faults (safe state) | back to normal | "
         "worst RMSE / baseline | between faults: RMSE mean / max [mm] (periods above) | EMCY | heap [MB] | RSS [MB] | "
         "CPU [us/cycle] | "
         "step p99 / max [us] |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
}

std::string soakIntervalLine(const SoakInterval& i) {
  char b[512];
  std::snprintf(
      b, sizeof b,
      "| %.2f | %llu | %llu | %llu | %llu | %llu (%llu) | %llu/%llu | %.3f | %.4f / %.4f (%llu) | %llu | %.3f | %.1f | "
      "%.2f | %.1f / %.0f |\n",
      i.end_h, static_cast<unsigned long long>(i.cycles), static_cast<unsigned long long>(i.missed_syncs),
      static_cast<unsigned long long>(i.lost_clean), static_cast<unsigned long long>(i.ring_dropped),
      static_cast<unsigned long long>(i.faults), static_cast<unsigned long long>(i.reacted),
      static_cast<unsigned long long>(i.back), static_cast<unsigned long long>(i.checked), i.worst_ratio,
      i.clean.rmse_mean, i.clean.rmse_max, static_cast<unsigned long long>(i.clean.bad),
      static_cast<unsigned long long>(i.emcy), i.usage.heap_mb, i.usage.rss_mb, i.usage.cpu_us_per_cycle,
      i.usage.step_us_p99, i.usage.step_us_max);
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
  const double heap0 = r.intervals.empty() ? 0.0 : r.intervals.front().usage.heap_mb;
  const double heap1 = r.intervals.empty() ? 0.0 : r.intervals.back().usage.heap_mb;
  const double rss0 = r.intervals.empty() ? 0.0 : r.intervals.front().usage.rss_mb;
  const double rss1 = r.intervals.empty() ? 0.0 : r.intervals.back().usage.rss_mb;
  std::snprintf(b, sizeof b,
                "\n%.2f h simulated (%s, seed %llu) in %.0f s wall time; baseline tracking RMSE %.4f mm (%d periods "
                "before the first fault), tolerance %.0f %% + 0.005 mm\n",
                o.hours, control::toString(o.kind), static_cast<unsigned long long>(o.seed), r.wall_s, r.baseline_rmse,
                o.baseline_periods, o.tolerance * 100.0);
  s += b;
  std::snprintf(
      b, sizeof b,
      "memory: heap in use (%s) %.3f MB after the first report, %.3f MB at the end: %+.0f bytes (limit %.0f); "
      "RSS %.1f -> %.1f MB: %s\n",
      r.asan ? "AddressSanitizer allocator" : "mallinfo2", heap0, heap1, r.heap_growth_bytes, o.heap_growth_limit, rss0,
      rss1, r.memory_ok ? "ok" : "FAILED");
  s += b;
  std::uint64_t lost = 0, dropped = 0, cycles = 0, gaps = 0;
  for (const auto& i : r.intervals)
    lost += i.lost_clean, dropped += i.ring_dropped, cycles += i.cycles, gaps += i.missed_syncs;
  std::snprintf(b, sizeof b,
                "cycle: %llu control cycles, %llu SYNC gaps (all during SYNC faults), %llu periods outside faults "
                "without exactly one cycle, %llu records lost; CPU per cycle last third / first third %.2f (limit "
                "%.2f): %s\n",
                static_cast<unsigned long long>(cycles), static_cast<unsigned long long>(gaps),
                static_cast<unsigned long long>(lost), static_cast<unsigned long long>(dropped), r.cpu_drift,
                o.cpu_drift_limit, r.cycle_ok && r.timing_ok ? "ok" : "FAILED");
  s += b;
  std::uint64_t clean = 0, clean_bad = 0;
  for (const auto& i : r.intervals) clean += i.clean.periods, clean_bad += i.clean.bad;
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

}  // namespace pamc::rig
