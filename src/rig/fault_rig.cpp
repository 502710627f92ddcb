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
// Another master moves the faulted sensor's position TPDO (CiA 301: disabled first, then the new COB-ID).
void movePdo(Rig& r, std::uint32_t from, std::uint32_t to) {
  r.sdoWrite32(r.sensor_id, 0x1800, 1, 0x80000000u | from);
  r.sdoWrite32(r.sensor_id, 0x1800, 1, to);
}
void pdoAway(Rig& r) { movePdo(r, 0x180u + r.sensor_id, 0x190u); }
void pdoBack(Rig& r) { movePdo(r, 0x190u, 0x180u + r.sensor_id); }

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
     "sensor's position TPDO on COB-ID 0x190 when the controller starts, moved back after 2 s", 2.0, kAtStart, pdoAway,
     pdoBack},
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

// Channel c's tracking RMSE over [from, to) of bus time.
double rmse(const Rig& r, std::size_t c, TimeUs from, TimeUs to) {
  double acc = 0;
  std::size_t n = 0;
  for (std::size_t i = 0; i < r.recs.size(); ++i) {
    if (r.recs[i].channel != c || r.rec_us[i] < from || r.rec_us[i] >= to) continue;
    const double e = r.traj.at(r.recs[i].t) - r.recs[i].y;
    acc += e * e;
    ++n;
  }
  return n ? std::sqrt(acc / static_cast<double>(n)) : std::numeric_limits<double>::quiet_NaN();
}

// Channel c's largest command step from one of its cycles to the next, both in [from, to) and in control.
double maxStep(const Rig& r, std::size_t c, TimeUs from, TimeUs to) {
  double m = 0;
  const nodes::CycleRecord* prev = nullptr;
  TimeUs prev_us = 0;
  for (std::size_t i = 0; i < r.recs.size(); ++i) {
    const nodes::CycleRecord& x = r.recs[i];
    if (x.channel != c) continue;
    const bool inside = r.rec_us[i] >= from && r.rec_us[i] < to && prev && prev_us >= from;
    if (inside && x.fault == 0 && prev->fault == 0) m = std::max(m, std::fabs(x.u - prev->u));
    prev = &x;
    prev_us = r.rec_us[i];
  }
  return m;
}

// The times of one run (bus time): the injection, the end of the fault, the end of the run.
struct Times {
  TimeUs inj = 0, end = 0, stop = 0;
};

// Runs the rig up to the injection (f injected before the controller starts for an at-start setup).
Times settle(Rig& r, BusFault setup, BusFault f, double fault_s, const FaultRigOptions& o) {
  const TimeUs limit = static_cast<TimeUs>((o.preroll_s + o.inject_at_s + 30.0) * 1e6);
  if (atStart(setup)) {
    r.emcy_from = 0;
    begin(r, f);
    r.step(kPeriod);
    r.startController();
  }
  while (!atStart(setup) && r.ctrl->runTime() < o.inject_at_s && r.bus.now() < limit) r.step(kPeriod);
  if (r.bus.now() >= limit) throw std::runtime_error("fault rig: the controller did not start");
  Times t;
  t.inj = r.bus.now();
  t.end = t.inj + static_cast<TimeUs>(std::llround(fault_s * 1e6));
  t.stop = t.end + static_cast<TimeUs>(std::llround(o.after_s * 1e6));
  return t;
}

// What a run follows of the row's channel as it goes: its fault, its valve output, its return.
struct Watch {
  bool injected = true, faulted = false, safe = false;
  double safe_volts = 0;
};

void observe(Rig& r, const Times& t, Watch& w, FaultRun& out) {
  const std::size_t c = r.channel;
  const TimeUs now = r.bus.now();
  const TimeUs reacted = r.ctrl->reactedAtUs(c);
  if (reacted != canopen::kNever && out.detect_cycles < 0)
    out.detect_cycles = static_cast<double>(std::max(reacted, t.inj) - t.inj) / kPeriod;
  if (r.ctrl->channelFault(c) != Fault::None && !w.faulted) {
    w.faulted = true;
    out.first = r.ctrl->channelFault(c);
  }
  if (!w.safe && w.faulted && std::fabs(r.emu->valveVolts(c) - w.safe_volts) < 1e-9) {
    w.safe = true;
    out.safe_cycles = static_cast<double>(std::max(r.emu->valveChangedUs(c), t.inj) - t.inj) / kPeriod;
  }
  if (w.faulted && out.resume_s < 0 && r.ctrl->channelFault(c) == Fault::None && now >= t.end)
    out.resume_s = static_cast<double>(now - t.end) * 1e-6;
}

// From the injection to the end of the run, the fault cleared after its time.
void follow(Rig& r, BusFault f, const Times& t, FaultRun& out) {
  Watch w;
  w.safe_volts = pd::valveVolts(r.ctrl->safeCommand());
  while (r.bus.now() < t.stop) {
    // Fine steps around the fault, for the reaction times.
    const bool fine = r.bus.now() < t.end + 300'000;
    r.step(fine ? 100 : kPeriod);
    if (w.injected && r.bus.now() >= t.end) {
      end(r, f);
      w.injected = false;
    }
    observe(r, t, w, out);
  }
}

// The EMCY codes after the injection (each once, in order), whether a reset followed, the channels named.
void collectEmcy(const Rig& r, FaultRun& out) {
  out.emcy.clear();
  for (std::size_t i = 0; i < r.emcy.size(); ++i) {
    const std::uint16_t c = r.emcy[i];
    if (c == 0) {
      out.emcy_reset = true;
      continue;
    }
    if (std::find(out.emcy.begin(), out.emcy.end(), c) == out.emcy.end()) out.emcy.push_back(c);
    if (std::find(out.channels.emcy_named.begin(), out.channels.emcy_named.end(), r.emcy_channel[i]) ==
        out.channels.emcy_named.end())
      out.channels.emcy_named.push_back(r.emcy_channel[i]);
  }
  std::sort(out.channels.emcy_named.begin(), out.channels.emcy_named.end());
}

// The figures at the end of the run: the row's channel's, and each channel's tracking and safe cycles.
void measure(const Rig& r, const Times& t, const std::vector<FaultCounters>& fc0, bool at_start, FaultRun& out) {
  const std::size_t ch = r.channel;
  const TimeUs t_resume = out.resume_s >= 0 ? t.end + static_cast<TimeUs>(out.resume_s * 1e6) : t.inj;
  out.max_step_v = maxStep(r, ch, t_resume, (out.resume_s >= 0 ? t_resume : t.end) + 3'000'000);
  out.step_before_v = maxStep(r, ch, t.inj - 1'000'000, t.inj);
  for (std::size_t c = 0; c < r.ctrl->channels(); ++c) {
    out.channels.rmse_end.push_back(rmse(r, c, t.stop - 2'000'000, t.stop));
    out.channels.rmse_fault.push_back(rmse(r, c, t.inj, t.end + 1'000'000));
    out.channels.safe_cycles.push_back(r.ctrl->channelCounters(c).safe_cycles - fc0[c].safe_cycles);
  }
  collectEmcy(r, out);
  out.recovered = r.ctrl->channelFault(ch) == Fault::None && r.ctrl->running();
  std::uint64_t cycles = 0;
  for (std::size_t i = 0; i < r.rec_us.size(); ++i)
    cycles += r.recs[i].channel == ch && r.rec_us[i] > t.inj && r.rec_us[i] <= t.stop;
  const auto expected = static_cast<std::uint64_t>((t.stop - t.inj) / kPeriod);
  // (Before the loop's first start there are no records to count.)
  out.cycles_without_sync = expected > cycles && !at_start ? expected - cycles : 0;
  out.fc = r.ctrl->faultCounters();
  out.samples_lost = r.ctrl->channelCounters(ch).samples_missing - fc0[ch].samples_missing;
  out.counters = r.ctrl->node().counters();
  out.bus_dropped = r.bus.framesDropped();
}

// One run: the rig set up for `setup`, fault f injected (None: the reference run) for fault_s.
FaultRun runOne(BusFault setup, BusFault f, double fault_s, const FaultRigOptions& o) {
  Rig r(setup, o);
  FaultRun out;
  out.fault = f;
  out.fault_s = fault_s;
  out.channels.faulted = o.channel;
  // Settle, then inject right after a SYNC; or inject, then start the controller.
  const Times t = settle(r, setup, f, fault_s, o);
  r.emcy_from = t.inj;
  std::vector<FaultCounters> fc0;
  for (std::size_t c = 0; c < r.ctrl->channels(); ++c) fc0.push_back(r.ctrl->channelCounters(c));
  if (!atStart(setup)) begin(r, f);
  follow(r, f, t, out);
  measure(r, t, fc0, atStart(setup), out);
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
  const FaultRun ref = f == BusFault::None ? run : runOne(f, BusFault::None, faultSeconds(f), o);
  run.channels.rmse_base = ref.channels.rmse_end;
  run.channels.rmse_fault_base = ref.channels.rmse_fault;
  return run;
}

std::vector<FaultRun> runFaultTable(const std::vector<BusFault>& faults, const FaultRigOptions& o) {
  std::vector<FaultRun> out;
  for (BusFault f : faults.empty() ? allBusFaults() : faults) out.push_back(runBusFault(f, o));
  return out;
}

namespace {

std::string dataLost(const FaultRun& r) {
  char b[128];
  std::snprintf(b, sizeof b, "%llu sample%s", static_cast<unsigned long long>(r.samples_lost),
                r.samples_lost == 1 ? "" : "s");
  std::string lost = b;
  if (r.cycles_without_sync > 0) {
    std::snprintf(b, sizeof b, ", %llu cycles without SYNC", static_cast<unsigned long long>(r.cycles_without_sync));
    lost += b;
  }
  std::snprintf(b, sizeof b, "; %llu cycles safe", static_cast<unsigned long long>(r.safeCyclesTotal()));
  return lost + b;
}

// The cells of the one-muscle table, from "| fault" to "data lost |".
std::string rowCells(const FaultRun& r) {
  char b[512];
  std::string reaction =
      r.first != Fault::None ? toString(r.first) : (r.emcy.empty() ? "none (not detected)" : "warning only");
  std::string detect = r.detect_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.detect_cycles), b) : "-";
  std::string safe = r.safe_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.safe_cycles), b) : "-";
  std::string back = r.resume_s >= 0 ? (std::snprintf(b, sizeof b, "%.3f s", r.resume_s), b) : "-";
  std::snprintf(b, sizeof b, "| %s | %s | %s | %s | %s%s | %s | %s | %.3f (%.3f) | %.3f (%.3f) | %s |",
                busFaultDescription(r.fault).c_str(), reaction.c_str(), detect.c_str(), safe.c_str(),
                codes(r.emcy).c_str(), r.emcy_reset && !r.emcy.empty() ? " + reset" : "", r.recovered ? "yes" : "no",
                back.c_str(), r.max_step_v, r.step_before_v, r.rmseEnd(), r.rmseBase(), dataLost(r).c_str());
  return b;
}

// The other channels: the one whose RMSE of the last 2 s rose most over its reference run's, and those
// that sent the safe value (with their cycles safe).
std::string othersCell(const FaultRun& r) {
  std::size_t worst = r.channels.faulted;
  std::string safe;
  char b[128];
  for (std::size_t c = 0; c < r.channels.rmse_end.size(); ++c) {
    if (c == r.channels.faulted) continue;
    const double rise = r.channels.rmse_end[c] - r.channels.rmse_base[c];
    if (worst == r.channels.faulted || rise > r.channels.rmse_end[worst] - r.channels.rmse_base[worst]) worst = c;
    if (r.channels.safe_cycles[c] == 0) continue;
    std::snprintf(b, sizeof b, "%s%zu (%llu)", safe.empty() ? "" : ", ", c + 1,
                  static_cast<unsigned long long>(r.channels.safe_cycles[c]));
    safe += b;
  }
  if (worst == r.channels.faulted) return "-";
  std::snprintf(b, sizeof b, "%zu: %.3f (%.3f); ", worst + 1, r.channels.rmse_end[worst], r.channels.rmse_base[worst]);
  return b + (safe.empty() ? std::string("none safe") : "safe: " + safe);
}

std::string channelList(const std::vector<std::uint8_t>& v) {
  std::string s;
  for (std::uint8_t c : v) s += (s.empty() ? "" : ", ") + std::to_string(c);
  return s.empty() ? "-" : s;
}

}  // namespace

std::string faultTableMarkdown(const std::vector<FaultRun>& runs) {
  bool several = false;
  for (const auto& r : runs) several = several || r.channels.rmse_end.size() > 1;
  std::string s =
      "| fault injected | controller's reaction | cycles to reaction | cycles to valve safe | EMCY | recovered | "
      "control back after | max step after (before) [V] | RMSE last 2 s [mm] (no fault) | data lost |";
  s += several ? " EMCY naming channels | other channels: worst RMSE last 2 s [mm] (no fault); cycles safe |\n" : "\n";
  s += several ? "|---|---|---|---|---|---|---|---|---|---|---|---|\n" : "|---|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& r : runs) {
    s += rowCells(r);
    if (several) s += " " + channelList(r.channels.emcy_named) + " | " + othersCell(r) + " |";
    s += "\n";
  }
  return s;
}

}  // namespace pamc::rig
