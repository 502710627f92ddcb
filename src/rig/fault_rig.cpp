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

namespace pamc::rig {

using namespace detail;
using namespace nodes;

namespace detail {

Injection& inj(Rig& r) { return r.emu->inject(); }
void nothing(Rig&) {}

const FaultSpec kFaultSpecs[] = {
    {BusFault::None, "none", "none", 0.0, kPlain, nothing, nothing},
    {BusFault::SensorSilentShort, "sensor-silent-short", "sensor silent 100 ms", 0.1, kPlain,
     [](Rig& r) { inj(r).sensor_silent = true; }, [](Rig& r) { inj(r).sensor_silent = false; }},
    {BusFault::SensorSilentLong, "sensor-silent-long", "sensor silent 1 s", 1.0, kPlain,
     [](Rig& r) { inj(r).sensor_silent = true; }, [](Rig& r) { inj(r).sensor_silent = false; }},
    {BusFault::SensorReboot, "sensor-reboot", "sensor reboots (50 ms off, boot-up, Pre-operational)", 0.05, kPlain,
     [](Rig& r) { r.emu->rebootSensor(50'000); }, nothing},
    {BusFault::PdoLateInCycle, "pdo-late", "position PDOs 0.9 periods late, 200 ms", 0.2, kPlain,
     [](Rig& r) { inj(r).pdo_delay_us = 900; }, [](Rig& r) { inj(r).pdo_delay_us = 0; }},
    {BusFault::PdoLateCycle, "pdo-late-cycle", "position PDOs 1.2 periods late, 2 s", 2.0, kPlain,
     [](Rig& r) { inj(r).pdo_delay_us = 1200; }, [](Rig& r) { inj(r).pdo_delay_us = 0; }},
    {BusFault::PdoDropRandom, "pdo-drop-random", "5 % of position PDOs dropped, 2 s", 2.0, kPlain,
     [](Rig& r) { inj(r).drop_prob = 0.05; }, [](Rig& r) { inj(r).drop_prob = 0; }},
    {BusFault::PdoDropBurst, "pdo-drop-burst", "10 position PDOs in a row dropped", 0.01, kPlain,
     [](Rig& r) { inj(r).drop_next = 10; }, nothing},
    {BusFault::PdoDuplicate, "pdo-duplicate", "every position PDO twice, 2 s", 2.0, kPlain,
     [](Rig& r) { inj(r).pdo_duplicate = true; }, [](Rig& r) { inj(r).pdo_duplicate = false; }},
    {BusFault::SyncStop, "sync-stop", "SYNC producer stops 100 ms (controller consumes SYNC)", 0.1, kSyncSource,
     [](Rig& r) { r.sync->active = false; }, [](Rig& r) { r.sync->active = true; }},
    {BusFault::ValveSilentShort, "valve-silent-short", "valve silent 100 ms", 0.1, kPlain,
     [](Rig& r) { inj(r).valve_silent = true; }, [](Rig& r) { inj(r).valve_silent = false; }},
    {BusFault::ValveSilentLong, "valve-silent-long", "valve silent 1 s", 1.0, kPlain,
     [](Rig& r) { inj(r).valve_silent = true; }, [](Rig& r) { inj(r).valve_silent = false; }},
    {BusFault::FloodHalf, "flood-50", "1 Mbit/s bus 50 % loaded by ID 0x010, 2 s", 2.0, kTimedBus,
     [](Rig& r) { r.flood->begin(r.bus.now(), 2 * r.bus.frameTimeUs(canopen::makeFrame(0x10, 8)), 1); },
     [](Rig& r) { r.flood->end(); }},
    {BusFault::FloodFull, "flood-100", "1 Mbit/s bus 100 % loaded by ID 0x010, 200 ms", 0.2, kTimedBus,
     [](Rig& r) { r.flood->begin(r.bus.now(), r.bus.frameTimeUs(canopen::makeFrame(0x10, 8)), 2); },
     [](Rig& r) { r.flood->end(); }},
    {BusFault::PdoShortOnce, "pdo-short", "one position PDO with DLC 3", 0.001, kPlain,
     [](Rig& r) { inj(r).pdo_len = 3; }, [](Rig& r) { inj(r).pdo_len = -1; }},
    {BusFault::PdoLong, "pdo-long", "position PDOs with DLC 8, 200 ms", 0.2, kPlain, [](Rig& r) { inj(r).pdo_len = 8; },
     [](Rig& r) { inj(r).pdo_len = -1; }},
    {BusFault::SyncWrongLength, "sync-length", "SYNC with DLC 1, 100 ms (controller consumes SYNC)", 0.1, kSyncSource,
     [](Rig& r) { r.sync->len = 1; }, [](Rig& r) { r.sync->len = 0; }},
    {BusFault::HeartbeatWrongLength, "heartbeat-length", "sensor heartbeats with DLC 2, 1 s", 1.0, kPlain,
     [](Rig& r) { inj(r).heartbeat_len = 2; }, [](Rig& r) { inj(r).heartbeat_len = -1; }},
    {BusFault::DuplicateController, "dup-id-controller", "second node-ID 1 (boot-up, heartbeats), 1 s", 1.0,
     kDupController, [](Rig& r) { r.imp_ctrl->begin(r.bus.now()); }, [](Rig& r) { r.imp_ctrl->end(); }},
    {BusFault::DuplicateSensor, "dup-id-sensor", "second node-ID 2 (heartbeats, position PDOs), 1 s", 1.0, kDupSensor,
     [](Rig& r) { r.imp_sensor->begin(r.bus.now()); }, [](Rig& r) { r.imp_sensor->end(); }},
    // Error frames: error passive, error active again 100 ms later.
    {BusFault::ErrorPassive, "error-passive", "error frame: error passive, error active after 100 ms", 0.1, kPlain,
     [](Rig& r) { r.aux.send(errorFrame(0x04, 0x10)); }, [](Rig& r) { r.aux.send(errorFrame(0x04, 0x40)); }},
    {BusFault::BusOff, "bus-off", "error frame: bus off, restarted after 100 ms", 0.1, kPlain,
     [](Rig& r) { r.aux.send(errorFrame(0x40, 0)); }, [](Rig& r) { r.aux.send(errorFrame(0x100, 0)); }},
    {BusFault::CanOverflow, "can-overflow", "error frame: controller RX overflow", 0.001, kPlain,
     [](Rig& r) { r.aux.send(errorFrame(0x04, 0x01)); }, nothing},
    // Another master moved the TPDO (CiA 301: disabled first, then the new COB-ID); moved back after it.
    {BusFault::SensorPdoMovedAtStart, "pdo-moved-at-start",
     "sensor's position TPDO on COB-ID 0x190 when the controller starts, moved back after 2 s", 2.0, kAtStart,
     [](Rig& r) { r.sdoWrite32(2, 0x1800, 1, 0x80000182u), r.sdoWrite32(2, 0x1800, 1, 0x190u); },
     [](Rig& r) { r.sdoWrite32(2, 0x1800, 1, 0x80000190u), r.sdoWrite32(2, 0x1800, 1, 0x182u); }},
};

const FaultSpec& spec(BusFault f) {
  for (const auto& x : kFaultSpecs)
    if (x.fault == f) return x;
  return kFaultSpecs[0];
}
void begin(Rig& r, BusFault f) { spec(f).begin(r); }
void end(Rig& r, BusFault f) { spec(f).end(r); }

}  // namespace detail

namespace {

double rmse(const Rig& r, TimeUs from, TimeUs to) {
  double acc = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < r.recs.size(); ++i) {
    if (r.rec_us[i] < from || r.rec_us[i] >= to) continue;
    const double e = r.traj.at(r.recs[i].t) - r.recs[i].y;
    acc += e * e;
    ++n;
  }
  return n ? std::sqrt(acc / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

double maxStep(const Rig& r, TimeUs from, TimeUs to) {
  double m = 0;
  for (std::size_t i = 1; i < r.recs.size(); ++i) {
    if (r.rec_us[i] < from || r.rec_us[i] >= to || r.rec_us[i - 1] < from) continue;
    if (r.recs[i].fault != 0 || r.recs[i - 1].fault != 0) continue;
    m = std::max(m, std::fabs(r.recs[i].u - r.recs[i - 1].u));
  }
  return m;
}

// One run: the rig set up for `setup`, fault f injected (None: the reference run) for fault_s.
FaultRun runOne(BusFault setup, BusFault f, double fault_s, const FaultRigOptions& o) {
  Rig r(setup, o);
  FaultRun out;
  out.fault = f;
  out.fault_s = fault_s;
  // Settle, then inject right after a SYNC; or inject, then start the controller.
  const TimeUs limit = static_cast<TimeUs>((o.preroll_s + o.inject_at_s + 30.0) * 1e6);
  if (atStart(setup)) {
    r.emcy_from = 0;
    begin(r, f);
    r.step(kPeriod);
    r.startController();
  }
  while (!atStart(setup) && r.ctrl->runTime() < o.inject_at_s && r.bus.now() < limit) r.step(kPeriod);
  if (r.bus.now() >= limit) throw std::runtime_error("fault rig: the controller did not start");
  const TimeUs t_inj = r.bus.now();
  const TimeUs t_end = t_inj + static_cast<TimeUs>(std::llround(out.fault_s * 1e6));
  const TimeUs t_stop = t_end + static_cast<TimeUs>(std::llround(o.after_s * 1e6));
  r.emcy_from = t_inj;
  const FaultCounters fc0 = r.ctrl->faultCounters();
  if (!atStart(setup)) begin(r, f);
  bool injected = true, faulted = false, safe = false;
  const double safe_volts = pd::valveVolts(r.ctrl->safeCommand());
  while (r.bus.now() < t_stop) {
    // Fine steps around the fault, for the reaction times.
    const bool fine = r.bus.now() < t_end + 300'000;
    r.step(fine ? 100 : kPeriod);
    const TimeUs now = r.bus.now();
    if (injected && now >= t_end) {
      end(r, f);
      injected = false;
    }
    const TimeUs reacted = r.ctrl->reactedAtUs();
    if (reacted != canopen::kNever && out.detect_cycles < 0)
      out.detect_cycles = static_cast<double>(std::max(reacted, t_inj) - t_inj) / kPeriod;
    if (r.ctrl->fault() != Fault::None && !faulted) {
      faulted = true;
      out.first = r.ctrl->fault();
    }
    if (!safe && faulted && std::fabs(r.emu->valveVolts() - safe_volts) < 1e-9) {
      safe = true;
      out.safe_cycles = static_cast<double>(std::max(r.emu->valveChangedUs(), t_inj) - t_inj) / kPeriod;
    }
    if (faulted && out.resume_s < 0 && r.ctrl->fault() == Fault::None && now >= t_end)
      out.resume_s = static_cast<double>(now - t_end) * 1e-6;
  }
  const TimeUs t_resume = out.resume_s >= 0 ? t_end + static_cast<TimeUs>(out.resume_s * 1e6) : t_inj;
  out.max_step_v = maxStep(r, t_resume, (out.resume_s >= 0 ? t_resume : t_end) + 3'000'000);
  out.step_before_v = maxStep(r, t_inj - 1'000'000, t_inj);
  out.rmse_end = rmse(r, t_stop - 2'000'000, t_stop);
  out.emcy.clear();
  for (std::uint16_t c : r.emcy) {
    if (c == 0)
      out.emcy_reset = true;
    else if (std::find(out.emcy.begin(), out.emcy.end(), c) == out.emcy.end())
      out.emcy.push_back(c);
  }
  out.recovered = r.ctrl->fault() == Fault::None && r.ctrl->running();
  std::uint64_t cycles = 0;
  for (TimeUs t : r.rec_us) cycles += t > t_inj && t <= t_stop;
  const auto expected = static_cast<std::uint64_t>((t_stop - t_inj) / kPeriod);
  // (Before the loop's first start there are no records to count.)
  out.cycles_without_sync = expected > cycles && !atStart(setup) ? expected - cycles : 0;
  out.fc = r.ctrl->faultCounters();
  out.samples_lost = out.fc.samples_missing - fc0.samples_missing;
  out.safe_cycles_total = out.fc.safe_cycles - fc0.safe_cycles;
  out.counters = r.ctrl->node().counters();
  out.bus_dropped = r.bus.framesDropped();
  return out;
}

std::string codes(const std::vector<std::uint16_t>& v) {
  std::string s;
  for (std::uint16_t c : v) {
    char b[16];
    std::snprintf(b, sizeof b, "%s0x%04X", s.empty() ? "" : ", ", c);
    s += b;
  }
  return s.empty() ? "-" : s;
}

}  // namespace

std::vector<BusFault> allBusFaults() {
  std::vector<BusFault> v;
  for (const auto& x : kFaultSpecs)
    if (x.fault != BusFault::None) v.push_back(x.fault);
  return v;
}

std::vector<BusFault> runningBusFaults() {
  std::vector<BusFault> v;
  for (BusFault f : allBusFaults())
    if (!atStart(f)) v.push_back(f);
  return v;
}

const char* busFaultName(BusFault f) { return spec(f).name; }
std::string busFaultDescription(BusFault f) { return spec(f).description; }

FaultRun runBusFault(BusFault f, const FaultRigOptions& o) {
  FaultRun run = runOne(f, f, faultSeconds(f), o);
  // The reference: the same rig and the same window, nothing injected.
  run.rmse_base = f == BusFault::None ? run.rmse_end : runOne(f, BusFault::None, faultSeconds(f), o).rmse_end;
  return run;
}

std::vector<FaultRun> runFaultTable(const std::vector<BusFault>& faults, const FaultRigOptions& o) {
  std::vector<FaultRun> out;
  for (BusFault f : faults.empty() ? allBusFaults() : faults) out.push_back(runBusFault(f, o));
  return out;
}

std::string faultTableMarkdown(const std::vector<FaultRun>& runs) {
  std::string s =
      "| fault injected | controller's reaction | cycles to reaction | cycles to valve safe | EMCY | recovered | "
      "control back after | max step after (before) [V] | RMSE last 2 s [mm] (no fault) | data lost |\n"
      "|---|---|---|---|---|---|---|---|---|---|\n";
  char b[512];
  for (const auto& r : runs) {
    std::string reaction =
        r.first != Fault::None ? toString(r.first) : (r.emcy.empty() ? "none (not detected)" : "warning only");
    std::string detect = r.detect_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.detect_cycles), b) : "-";
    std::string safe = r.safe_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.safe_cycles), b) : "-";
    std::string back = r.resume_s >= 0 ? (std::snprintf(b, sizeof b, "%.3f s", r.resume_s), b) : "-";
    std::snprintf(b, sizeof b, "%llu sample%s", static_cast<unsigned long long>(r.samples_lost),
                  r.samples_lost == 1 ? "" : "s");
    std::string lost = b;
    if (r.cycles_without_sync > 0) {
      std::snprintf(b, sizeof b, ", %llu cycles without SYNC", static_cast<unsigned long long>(r.cycles_without_sync));
      lost += b;
    }
    std::snprintf(b, sizeof b, "; %llu cycles safe", static_cast<unsigned long long>(r.safe_cycles_total));
    lost += b;
    std::snprintf(b, sizeof b, "| %s | %s | %s | %s | %s%s | %s | %s | %.3f (%.3f) | %.3f (%.3f) | %s |\n",
                  busFaultDescription(r.fault).c_str(), reaction.c_str(), detect.c_str(), safe.c_str(),
                  codes(r.emcy).c_str(), r.emcy_reset && !r.emcy.empty() ? " + reset" : "", r.recovered ? "yes" : "no",
                  back.c_str(), r.max_step_v, r.step_before_v, r.rmse_end, r.rmse_base, lost.c_str());
    s += b;
  }
  return s;
}

}  // namespace pamc::rig
