#include "nodes/fault_rig.hpp"

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

using canopen::Frame;
using canopen::TimeUs;
using canopen::VirtualBus;

namespace {

constexpr TimeUs kPeriod = 1000;
constexpr double kSafeVolts = 0.0;  // 0x2020 default: vented

// A SYNC producer on its own (the controller consumes in the runs that use it).
class SyncSource : public canopen::BusClient {
 public:
  explicit SyncSource(canopen::Transport& t) : t_(t) {}
  void start(TimeUs now) { next_ = now + kPeriod; }
  bool active = true;
  std::uint8_t len = 0;
  std::uint64_t sent = 0;
  void onFrame(const Frame&, TimeUs) override {}
  void advance(TimeUs now) override {
    while (next_ != canopen::kNever && now >= next_) {
      if (active) {
        t_.send(canopen::makeFrame(0x80, len));
        ++sent;
      }
      next_ += kPeriod;
    }
  }
  TimeUs nextDeadline() const override { return next_; }

 private:
  canopen::Transport& t_;
  TimeUs next_ = canopen::kNever;
};

// Sends 8-byte frames with a high-priority identifier at a fixed interval.
class Flooder : public canopen::BusClient {
 public:
  explicit Flooder(canopen::Transport& t) : t_(t) {}
  void begin(TimeUs now, TimeUs interval, int prefill) {
    interval_ = interval;
    for (int i = 0; i < prefill; ++i) send();
    next_ = now + interval_;
  }
  void end() { next_ = canopen::kNever; }
  void onFrame(const Frame&, TimeUs) override {}
  void advance(TimeUs now) override {
    while (next_ != canopen::kNever && now >= next_) {
      send();
      next_ += interval_;
    }
  }
  TimeUs nextDeadline() const override { return next_; }
  std::uint64_t sent = 0;

 private:
  void send() {
    const std::uint8_t d[8] = {0xAA, 0x55, 0xAA, 0x55, 0xAA, 0x55, 0xAA, 0x55};
    t_.send(canopen::makeFrame(0x010, 8, d));
    ++sent;
  }
  canopen::Transport& t_;
  TimeUs interval_ = kPeriod;
  TimeUs next_ = canopen::kNever;
};

// A second node with an ID already in use: boot-up, heartbeats every 100 ms (Operational), and - as
// a second sensor - a position PDO on every SYNC.
class Impostor : public canopen::BusClient {
 public:
  Impostor(canopen::Transport& t, std::uint8_t id, bool sensor) : t_(t), id_(id), sensor_(sensor) {}
  void begin(TimeUs now) {
    const std::uint8_t boot = 0;
    t_.send(canopen::makeFrame(0x700u + id_, 1, &boot));
    next_ = now + 100'000;
    on_ = true;
  }
  void end() {
    on_ = false;
    next_ = canopen::kNever;
  }
  void onFrame(const Frame& f, TimeUs) override {
    if (!on_ || !sensor_ || f.id != 0x80 || f.error()) return;
    std::uint8_t d[4];
    canopen::putU32(d, 10000);  // 10 mm: not what the real sensor says
    t_.send(canopen::makeFrame(0x180u + id_, 4, d));
  }
  void advance(TimeUs now) override {
    while (next_ != canopen::kNever && now >= next_) {
      const std::uint8_t op = 0x05;
      t_.send(canopen::makeFrame(0x700u + id_, 1, &op));
      next_ += 100'000;
    }
  }
  TimeUs nextDeadline() const override { return next_; }

 private:
  canopen::Transport& t_;
  std::uint8_t id_;
  bool sensor_;
  bool on_ = false;
  TimeUs next_ = canopen::kNever;
};

Frame errorFrame(std::uint32_t cls, std::uint8_t d1) {
  Frame f;
  f.flags = canopen::kFrameError;
  f.id = cls;
  f.len = 8;
  f.data[1] = d1;
  return f;
}

bool consumesSync(BusFault f) { return f == BusFault::SyncStop || f == BusFault::SyncWrongLength; }
bool timedBus(BusFault f) { return f == BusFault::FloodHalf || f == BusFault::FloodFull; }

double faultSeconds(BusFault f) {
  switch (f) {
    case BusFault::None: return 0.0;
    case BusFault::SensorSilentShort: return 0.1;
    case BusFault::SensorSilentLong: return 1.0;
    case BusFault::SensorReboot: return 0.05;
    case BusFault::PdoLateInCycle: return 0.2;
    case BusFault::PdoLateCycle: return 2.0;
    case BusFault::PdoDropRandom: return 2.0;
    case BusFault::PdoDropBurst: return 0.01;
    case BusFault::PdoDuplicate: return 2.0;
    case BusFault::SyncStop: return 0.1;
    case BusFault::ValveSilentShort: return 0.1;
    case BusFault::ValveSilentLong: return 1.0;
    case BusFault::FloodHalf: return 2.0;
    case BusFault::FloodFull: return 0.2;
    case BusFault::PdoShortOnce: return 0.001;
    case BusFault::PdoLong: return 0.2;
    case BusFault::SyncWrongLength: return 0.1;
    case BusFault::HeartbeatWrongLength: return 1.0;
    case BusFault::DuplicateController: return 1.0;
    case BusFault::DuplicateSensor: return 1.0;
    case BusFault::ErrorPassive: return 0.1;
    case BusFault::BusOff: return 0.1;
    case BusFault::CanOverflow: return 0.001;
  }
  return 0.0;
}

// The whole rig of one run.
struct Rig {
  // f sets the rig up for that fault (SYNC source, timed bus, second node); nothing is injected yet.
  // soak: everything any fault needs at once - the controller consumes the SYNC of a separate producer,
  // the bus has 1 Mbit/s timing, a flooder and a second node-ID 1 and 2 are on it (all idle).
  Rig(BusFault f, const FaultRigOptions& o, bool soak = false)
      : bus(), cport(bus.addPort()), eport(bus.addPort()), aux(bus.addPort()) {
    const bool consume = soak || consumesSync(f);
    if (soak || timedBus(f)) bus.setBitrate(1'000'000, 32);
    ControllerNodeConfig c;
    c.eds_path = o.od_dir + "/controller.eds";
    c.kind = static_cast<int>(o.kind);
    c.gains_from_config = true;
    c.ctrl.kp = o.kp;
    c.ctrl.ki = o.ki;
    c.ctrl.kc = o.kc;
    c.ctrl.model = plant::PlantConfig::defaults().truth;
    c.has_trajectory = true;
    c.trajectory = sim::Trajectory::sine(0.2, 5.0, 15.0);
    c.preroll_s = o.preroll_s;
    c.produce_sync = !consume;
    traj = c.trajectory;
    EmulatorConfig e;
    e.sensor_eds = o.od_dir + "/sensor.eds";
    e.valve_eds = o.od_dir + "/valve.eds";
    e.seed = o.seed;
    ctrl = std::make_unique<ControllerNode>(c, cport, [this] { return bus.now(); });
    emu = std::make_unique<EmulatorNodes>(e, eport);
    cport.setClient(&ctrl->node());
    eport.setClient(emu.get());
    if (consume) {
      auto& p = bus.addPort();
      sync = std::make_unique<SyncSource>(p);
      p.setClient(sync.get());
    }
    if (soak || timedBus(f)) {
      auto& p = bus.addPort();
      flood = std::make_unique<Flooder>(p);
      p.setClient(flood.get());
    }
    if (soak || f == BusFault::DuplicateController) {
      auto& p = bus.addPort();
      imp_ctrl = std::make_unique<Impostor>(p, 1, false);
      p.setClient(imp_ctrl.get());
    }
    if (soak || f == BusFault::DuplicateSensor) {
      auto& p = bus.addPort();
      imp_sensor = std::make_unique<Impostor>(p, 2, true);
      p.setClient(imp_sensor.get());
    }
    bus.addTap([this](const Frame& fr, TimeUs t) {
      if (fr.id != 0x81 || fr.len != 8 || fr.error()) return;
      ++emcy_frames;
      if (t >= emcy_from) emcy.push_back(canopen::getU16(fr.data));
    });
    emu->start(0);
    ctrl->start(0);
    if (sync) sync->start(0);
  }
  void step(TimeUs dt) {
    bus.advanceBy(dt);
    CycleRecord r;
    while (ctrl->records().pop(r)) {
      recs.push_back(r);
      rec_us.push_back(bus.now());
    }
  }

  VirtualBus bus;
  VirtualBus::Port &cport, &eport, &aux;
  std::unique_ptr<ControllerNode> ctrl;
  std::unique_ptr<EmulatorNodes> emu;
  std::unique_ptr<SyncSource> sync;
  std::unique_ptr<Flooder> flood;
  std::unique_ptr<Impostor> imp_ctrl, imp_sensor;
  sim::Trajectory traj;
  std::vector<CycleRecord> recs;
  std::vector<TimeUs> rec_us;
  std::vector<std::uint16_t> emcy;
  std::uint64_t emcy_frames = 0;
  TimeUs emcy_from = canopen::kNever;
};

void begin(Rig& r, BusFault f) {
  auto& inj = r.emu->inject();
  const TimeUs now = r.bus.now();
  switch (f) {
    case BusFault::None: break;
    case BusFault::SensorSilentShort:
    case BusFault::SensorSilentLong: inj.sensor_silent = true; break;
    case BusFault::SensorReboot: r.emu->rebootSensor(50'000); break;
    case BusFault::PdoLateInCycle: inj.pdo_delay_us = 900; break;
    case BusFault::PdoLateCycle: inj.pdo_delay_us = 1200; break;
    case BusFault::PdoDropRandom: inj.drop_prob = 0.05; break;
    case BusFault::PdoDropBurst: inj.drop_next = 10; break;
    case BusFault::PdoDuplicate: inj.pdo_duplicate = true; break;
    case BusFault::SyncStop: r.sync->active = false; break;
    case BusFault::ValveSilentShort:
    case BusFault::ValveSilentLong: inj.valve_silent = true; break;
    case BusFault::FloodHalf: r.flood->begin(now, 2 * r.bus.frameTimeUs(canopen::makeFrame(0x10, 8)), 1); break;
    case BusFault::FloodFull: r.flood->begin(now, r.bus.frameTimeUs(canopen::makeFrame(0x10, 8)), 2); break;
    case BusFault::PdoShortOnce: inj.pdo_len = 3; break;
    case BusFault::PdoLong: inj.pdo_len = 8; break;
    case BusFault::SyncWrongLength: r.sync->len = 1; break;
    case BusFault::HeartbeatWrongLength: inj.heartbeat_len = 2; break;
    case BusFault::DuplicateController: r.imp_ctrl->begin(now); break;
    case BusFault::DuplicateSensor: r.imp_sensor->begin(now); break;
    case BusFault::ErrorPassive: r.aux.send(errorFrame(0x04, 0x10)); break;
    case BusFault::BusOff: r.aux.send(errorFrame(0x40, 0)); break;
    case BusFault::CanOverflow: r.aux.send(errorFrame(0x04, 0x01)); break;
  }
}

void end(Rig& r, BusFault f) {
  auto& inj = r.emu->inject();
  switch (f) {
    case BusFault::SensorSilentShort:
    case BusFault::SensorSilentLong: inj.sensor_silent = false; break;
    case BusFault::PdoLateInCycle:
    case BusFault::PdoLateCycle: inj.pdo_delay_us = 0; break;
    case BusFault::PdoDropRandom: inj.drop_prob = 0; break;
    case BusFault::PdoDuplicate: inj.pdo_duplicate = false; break;
    case BusFault::SyncStop: r.sync->active = true; break;
    case BusFault::ValveSilentShort:
    case BusFault::ValveSilentLong: inj.valve_silent = false; break;
    case BusFault::FloodHalf:
    case BusFault::FloodFull: r.flood->end(); break;
    case BusFault::PdoShortOnce:
    case BusFault::PdoLong: inj.pdo_len = -1; break;
    case BusFault::SyncWrongLength: r.sync->len = 0; break;
    case BusFault::HeartbeatWrongLength: inj.heartbeat_len = -1; break;
    case BusFault::DuplicateController: r.imp_ctrl->end(); break;
    case BusFault::DuplicateSensor: r.imp_sensor->end(); break;
    case BusFault::ErrorPassive: r.aux.send(errorFrame(0x04, 0x40)); break;  // back to error active
    case BusFault::BusOff: r.aux.send(errorFrame(0x100, 0)); break;          // restarted
    default: break;
  }
}

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
  // Settle, then inject right after a SYNC.
  const TimeUs limit = static_cast<TimeUs>((o.preroll_s + o.inject_at_s + 30.0) * 1e6);
  while (r.ctrl->runTime() < o.inject_at_s && r.bus.now() < limit) r.step(kPeriod);
  if (r.bus.now() >= limit) throw std::runtime_error("fault rig: the controller did not start");
  const TimeUs t_inj = r.bus.now();
  const TimeUs t_end = t_inj + static_cast<TimeUs>(std::llround(out.fault_s * 1e6));
  const TimeUs t_stop = t_end + static_cast<TimeUs>(std::llround(o.after_s * 1e6));
  r.emcy_from = t_inj;
  const FaultCounters fc0 = r.ctrl->faultCounters();
  begin(r, f);
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
    if (c == 0) out.emcy_reset = true;
    else if (std::find(out.emcy.begin(), out.emcy.end(), c) == out.emcy.end()) out.emcy.push_back(c);
  }
  out.recovered = r.ctrl->fault() == Fault::None && r.ctrl->running();
  std::uint64_t cycles = 0;
  for (TimeUs t : r.rec_us) cycles += t > t_inj && t <= t_stop;
  const auto expected = static_cast<std::uint64_t>((t_stop - t_inj) / kPeriod);
  out.cycles_without_sync = expected > cycles ? expected - cycles : 0;
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
  return {BusFault::SensorSilentShort,  BusFault::SensorSilentLong,   BusFault::SensorReboot,
          BusFault::PdoLateInCycle,     BusFault::PdoLateCycle,       BusFault::PdoDropRandom,
          BusFault::PdoDropBurst,       BusFault::PdoDuplicate,       BusFault::SyncStop,
          BusFault::ValveSilentShort,   BusFault::ValveSilentLong,    BusFault::FloodHalf,
          BusFault::FloodFull,          BusFault::PdoShortOnce,       BusFault::PdoLong,
          BusFault::SyncWrongLength,    BusFault::HeartbeatWrongLength, BusFault::DuplicateController,
          BusFault::DuplicateSensor,    BusFault::ErrorPassive,       BusFault::BusOff,
          BusFault::CanOverflow};
}

const char* busFaultName(BusFault f) {
  switch (f) {
    case BusFault::None: return "none";
    case BusFault::SensorSilentShort: return "sensor-silent-short";
    case BusFault::SensorSilentLong: return "sensor-silent-long";
    case BusFault::SensorReboot: return "sensor-reboot";
    case BusFault::PdoLateInCycle: return "pdo-late";
    case BusFault::PdoLateCycle: return "pdo-late-cycle";
    case BusFault::PdoDropRandom: return "pdo-drop-random";
    case BusFault::PdoDropBurst: return "pdo-drop-burst";
    case BusFault::PdoDuplicate: return "pdo-duplicate";
    case BusFault::SyncStop: return "sync-stop";
    case BusFault::ValveSilentShort: return "valve-silent-short";
    case BusFault::ValveSilentLong: return "valve-silent-long";
    case BusFault::FloodHalf: return "flood-50";
    case BusFault::FloodFull: return "flood-100";
    case BusFault::PdoShortOnce: return "pdo-short";
    case BusFault::PdoLong: return "pdo-long";
    case BusFault::SyncWrongLength: return "sync-length";
    case BusFault::HeartbeatWrongLength: return "heartbeat-length";
    case BusFault::DuplicateController: return "dup-id-controller";
    case BusFault::DuplicateSensor: return "dup-id-sensor";
    case BusFault::ErrorPassive: return "error-passive";
    case BusFault::BusOff: return "bus-off";
    case BusFault::CanOverflow: return "can-overflow";
  }
  return "?";
}

std::string busFaultDescription(BusFault f) {
  switch (f) {
    case BusFault::None: return "none";
    case BusFault::SensorSilentShort: return "sensor silent 100 ms";
    case BusFault::SensorSilentLong: return "sensor silent 1 s";
    case BusFault::SensorReboot: return "sensor reboots (50 ms off, boot-up, Pre-operational)";
    case BusFault::PdoLateInCycle: return "position PDOs 0.9 periods late, 200 ms";
    case BusFault::PdoLateCycle: return "position PDOs 1.2 periods late, 2 s";
    case BusFault::PdoDropRandom: return "5 % of position PDOs dropped, 2 s";
    case BusFault::PdoDropBurst: return "10 position PDOs in a row dropped";
    case BusFault::PdoDuplicate: return "every position PDO twice, 2 s";
    case BusFault::SyncStop: return "SYNC producer stops 100 ms (controller consumes SYNC)";
    case BusFault::ValveSilentShort: return "valve silent 100 ms";
    case BusFault::ValveSilentLong: return "valve silent 1 s";
    case BusFault::FloodHalf: return "1 Mbit/s bus 50 % loaded by ID 0x010, 2 s";
    case BusFault::FloodFull: return "1 Mbit/s bus 100 % loaded by ID 0x010, 200 ms";
    case BusFault::PdoShortOnce: return "one position PDO with DLC 3";
    case BusFault::PdoLong: return "position PDOs with DLC 8, 200 ms";
    case BusFault::SyncWrongLength: return "SYNC with DLC 1, 100 ms (controller consumes SYNC)";
    case BusFault::HeartbeatWrongLength: return "sensor heartbeats with DLC 2, 1 s";
    case BusFault::DuplicateController: return "second node-ID 1 (boot-up, heartbeats), 1 s";
    case BusFault::DuplicateSensor: return "second node-ID 2 (heartbeats, position PDOs), 1 s";
    case BusFault::ErrorPassive: return "error frame: error passive, error active after 100 ms";
    case BusFault::BusOff: return "error frame: bus off, restarted after 100 ms";
    case BusFault::CanOverflow: return "error frame: controller RX overflow";
  }
  return "?";
}

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
    std::string reaction = r.first != Fault::None ? toString(r.first) : (r.emcy.empty() ? "none (not detected)" : "warning only");
    std::string detect = r.detect_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.detect_cycles), b) : "-";
    std::string safe = r.safe_cycles >= 0 ? (std::snprintf(b, sizeof b, "%.1f", r.safe_cycles), b) : "-";
    std::string back = r.resume_s >= 0 ? (std::snprintf(b, sizeof b, "%.3f s", r.resume_s), b) : "-";
    std::snprintf(b, sizeof b, "%llu sample%s", static_cast<unsigned long long>(r.samples_lost), r.samples_lost == 1 ? "" : "s");
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

namespace {

// An SDO client made of raw frames on the rig's spare port, so a test can put SYNCs between the
// frames of one transfer.
struct SdoTool {
  explicit SdoTool(Rig& r) : r(r) {
    r.bus.addTap([this](const Frame& f, TimeUs) {
      if (f.id == 0x581 && f.len == 8) {
        response = f;
        answered = true;
      }
    });
  }
  Frame request(std::uint8_t cmd, std::uint16_t idx, std::uint8_t sub, const std::uint8_t* d, std::size_t n) {
    std::uint8_t b[8] = {cmd, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, 0, 0, 0, 0};
    std::memcpy(b + 4, d, std::min<std::size_t>(n, 4));
    return canopen::makeFrame(0x601, 8, b);
  }
  // Sends f and runs the bus (gap_us per step) until the server answers; returns the response.
  Frame exchange(const Frame& f, TimeUs gap_us) {
    answered = false;
    r.aux.send(f);
    for (int i = 0; i < 1000 && !answered; ++i) r.step(gap_us);
    return response;
  }
  static std::uint32_t code(const Frame& f) { return f.data[0] == 0x80 ? canopen::getU32(f.data + 4) : 0; }
  // Expedited download of 1, 2 or 4 bytes.
  std::uint32_t write(std::uint16_t idx, std::uint8_t sub, const void* v, std::size_t n) {
    const std::uint8_t cmd = static_cast<std::uint8_t>(0x23 | ((4 - n) << 2));
    return code(exchange(request(cmd, idx, sub, static_cast<const std::uint8_t*>(v), n), 100));
  }
  std::uint32_t writeU8(std::uint16_t idx, std::uint8_t sub, std::uint8_t v) { return write(idx, sub, &v, 1); }
  std::uint32_t writeU32(std::uint16_t idx, std::uint8_t sub, std::uint32_t v) { return write(idx, sub, &v, 4); }
  // Segmented download of a REAL64; gap_us of bus time (with its SYNCs) between the frames.
  std::uint32_t writeDouble(std::uint16_t idx, std::uint8_t sub, double v, TimeUs gap_us = 100,
                            const std::function<void()>& between = {}) {
    std::uint8_t d[8];
    std::memcpy(d, &v, 8);
    const std::uint8_t size[4] = {8, 0, 0, 0};
    Frame f = exchange(request(0x21, idx, sub, size, 4), gap_us);
    if (code(f) != 0) return code(f);
    std::uint8_t seg1[8] = {0x00, d[0], d[1], d[2], d[3], d[4], d[5], d[6]};
    f = exchange(canopen::makeFrame(0x601, 8, seg1), gap_us);
    if (code(f) != 0) return code(f);
    if (between) between();
    std::uint8_t seg2[8] = {0x1D, d[7], 0, 0, 0, 0, 0, 0};  // toggle 1, 6 bytes unused, last
    return code(exchange(canopen::makeFrame(0x601, 8, seg2), gap_us));
  }
  void nmt(std::uint8_t cmd) {
    const std::uint8_t b[2] = {cmd, 1};
    r.aux.send(canopen::makeFrame(0x000, 2, b));
    r.step(kPeriod);
  }
  Rig& r;
  Frame response;
  bool answered = false;
};

std::string hexCode(std::uint32_t c) {
  char b[24];
  std::snprintf(b, sizeof b, c ? "0x%08X" : "accepted", c);
  return b;
}

}  // namespace

std::vector<GuardRow> runParameterGuards(const FaultRigOptions& o) {
  Rig r(BusFault::None, o);
  SdoTool sdo(r);
  while (r.ctrl->runTime() < 2.0) r.step(kPeriod);
  std::vector<GuardRow> rows;
  auto& od = r.ctrl->node().od();
  const double kp0 = r.ctrl->activeParameters().kp;
  char b[256];
  // The set in use before a write, to tell whether the loop saw anything of it.
  struct Snapshot {
    double kp, ki, gamma, safe;
    int kind;
    bool operator==(const Snapshot& o) const {
      return kp == o.kp && ki == o.ki && gamma == o.gamma && safe == o.safe && kind == o.kind;
    }
  };
  auto snap = [&] {
    const auto& p = r.ctrl->activeParameters();
    return Snapshot{p.kp, p.ki, p.model.core().gamma, r.ctrl->safeCommand(), static_cast<int>(r.ctrl->kind())};
  };
  Snapshot before = snap();
  auto unchanged = [&] { return snap() == before ? "refused; the loop's set is unchanged" : "LOOP CHANGED"; };
  auto row = [&](const std::string& what, std::uint32_t expected, std::uint32_t got, const std::string& effect) {
    rows.push_back({what, expected, got, effect});
    before = snap();
  };
  const double nan = std::numeric_limits<double>::quiet_NaN(), inf = std::numeric_limits<double>::infinity();
  using namespace canopen;
  row("0x1001 error register (ro)", kAbortReadOnly, sdo.writeU8(0x1001, 0, 1), unchanged());
  row("0x2003:02 staged flag (ro)", kAbortReadOnly, sdo.writeU8(0x2003, 2, 1), unchanged());
  row("0x2004 (no such object)", kAbortNoObject, sdo.writeU8(0x2004, 0, 1), unchanged());
  row("0x2000:09 (no such sub-index)", kAbortNoSubIndex, sdo.writeDouble(0x2000, 9, 1.0), unchanged());
  row("kp 0x2000:01 = 20 V/mm (above the EDS limit 10)", kAbortValueTooHigh, sdo.writeDouble(0x2000, 1, 20.0), unchanged());
  row("kp 0x2000:01 = 5000 (far above the EDS limit 10)", kAbortValueTooHigh, sdo.writeDouble(0x2000, 1, 5000.0), unchanged());
  row("kp 0x2000:01 = -1", kAbortValueTooLow, sdo.writeDouble(0x2000, 1, -1.0), unchanged());
  row("ki 0x2000:02 = NaN", kAbortValueRange, sdo.writeDouble(0x2000, 2, nan), unchanged());
  row("ESO b0 0x2000:08 = 0", kAbortValueTooLow, sdo.writeDouble(0x2000, 8, 0.0), unchanged());
  row("UKF R0 0x2002:05 = 0", kAbortValueTooLow, sdo.writeDouble(0x2002, 5, 0.0), unchanged());
  row("UKF divergence bound 0x2002:09 = -1", kAbortValueTooLow, sdo.writeDouble(0x2002, 9, -1.0), unchanged());
  row("model k 0x2001:01 = inf", kAbortValueRange, sdo.writeDouble(0x2001, 1, inf), unchanged());
  row("stuck-sensor span 0x2022:03 = 20 V (above 10)", kAbortValueTooHigh, sdo.writeDouble(0x2022, 3, 20.0), unchanged());
  row("measuring range 0x2022:01 = 0", kAbortValueTooLow, sdo.writeDouble(0x2022, 1, 0.0), unchanged());
  row("safe valve voltage 0x2020 = 12 V", kAbortValueTooHigh, sdo.writeDouble(0x2020, 0, 12.0), unchanged());
  row("controller 0x2010 = 1 (PI) while Operational", kAbortDeviceState, sdo.writeU8(0x2010, 0, 1),
      snap() == before ? "refused; the controller is not switched under the running loop" : "LOOP CHANGED");
  row("trajectory 0x2011 = 2 while Operational", kAbortDeviceState, sdo.writeU8(0x2011, 0, 2), unchanged());
  row("SYNC period 0x1006 = 500 us while Operational", kAbortDeviceState, sdo.writeU32(0x1006, 0, 500), unchanged());
  row("heartbeat consumer 0x1016:01 = 0 while Operational", kAbortDeviceState, sdo.writeU32(0x1016, 1, 0),
      "refused; the sensor stays monitored");
  {
    const std::uint16_t zero = 0;
    row("valve command 0x3002 = 0 while Operational", kAbortDeviceState, sdo.write(0x3002, 0, &zero, 2),
        "refused; only the loop writes the valve");
  }
  row("position 0x3000 = 0 while Operational", kAbortDeviceState, sdo.writeU32(0x3000, 0, 0),
      "refused; only the sensor's PDO writes the position");
  // A segmented write with SYNCs between its frames: the entry changes with the last segment only.
  {
    bool half_written_seen = false;
    const std::uint32_t c = sdo.writeDouble(0x2000, 1, 0.12, 1000, [&] {
      for (int k = 0; k < 3; ++k) r.step(kPeriod);
      half_written_seen = od.entry(0x2000, 1).get<double>() != kp0;
    });
    for (int k = 0; k < 50; ++k) r.step(kPeriod);
    std::snprintf(b, sizeof b, "%s; staged (0x2003:02 = %u): after 50 cycles the loop still uses kp = %g",
                  half_written_seen ? "ENTRY CHANGED BEFORE THE LAST SEGMENT" : "entry unchanged until the last segment",
                  od.entry(0x2003, 2).get<std::uint8_t>(), r.ctrl->activeParameters().kp);
    row("kp 0x2000:01 = 0.12, segmented, 3 SYNCs between its segments", kSdoOk, c, b);
  }
  row("ki 0x2000:02 = 1.8", kSdoOk, sdo.writeDouble(0x2000, 2, 1.8), "staged");
  {
    // Commit: checked in the SDO server, taken by the loop at the next SYNC.
    const double step_before = [&] {
      double m = 0;
      for (std::size_t i = r.recs.size() - 500; i < r.recs.size(); ++i) m = std::max(m, std::fabs(r.recs[i].u - r.recs[i - 1].u));
      return m;
    }();
    const std::uint8_t applied0 = od.entry(0x2003, 3).get<std::uint8_t>();
    const std::size_t from = r.recs.size();
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 1);
    const double kp_right_after = r.ctrl->activeParameters().kp;
    int cycles = 0;
    while (r.ctrl->activeParameters().kp != 0.12 && cycles < 10) r.step(kPeriod), ++cycles;
    for (int k = 0; k < 3000; ++k) r.step(kPeriod);
    double m = 0;
    for (std::size_t i = std::max<std::size_t>(from, 1); i < r.recs.size(); ++i) m = std::max(m, std::fabs(r.recs[i].u - r.recs[i - 1].u));
    std::snprintf(b, sizeof b,
                  "kp %g until the cycle boundary, then kp %g, ki %g in use; 0x2003:03 %u -> %u; largest command step "
                  "in the next 3 s %.4f V (before %.4f V)",
                  kp_right_after, r.ctrl->activeParameters().kp, r.ctrl->activeParameters().ki, applied0,
                  od.entry(0x2003, 3).get<std::uint8_t>(), m, step_before);
    row("commit 0x2003:01 = 1", kSdoOk, c, b);
  }
  row("model gamma 0x2001:06 = -0.5 (beta + gamma < 0)", kSdoOk, sdo.writeDouble(0x2001, 6, -0.5), "staged");
  {
    const double gamma = r.ctrl->activeParameters().model.core().gamma;
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 1);
    r.step(kPeriod);
    std::snprintf(b, sizeof b, "refused: the loop keeps gamma = %g; the SDO answer carries the reason",
                  r.ctrl->activeParameters().model.core().gamma);
    (void)gamma;
    row("commit 0x2003:01 = 1 of that unstable model", kAbortParameterIncompatible, c, b);
  }
  {
    const std::uint32_t c = sdo.writeU8(0x2003, 1, 0);
    std::snprintf(b, sizeof b, "discarded: 0x2001:06 reads %g again, 0x2003:02 = %u",
                  od.entry(0x2001, 6).get<double>(), od.entry(0x2003, 2).get<std::uint8_t>());
    row("discard 0x2003:01 = 0", kSdoOk, c, b);
  }
  row("0x2003:01 = 2", kAbortValueTooHigh, sdo.writeU8(0x2003, 1, 2), unchanged());
  {
    // Switching the controller: stop the loop (NMT Pre-operational), write, start again.
    sdo.nmt(0x80);
    for (int k = 0; k < 5; ++k) r.step(kPeriod);
    const double valve = r.emu->valveVolts();
    const std::uint32_t c = sdo.writeU8(0x2010, 0, 1);
    sdo.nmt(0x01);
    for (int k = 0; k < 100; ++k) r.step(kPeriod);
    std::snprintf(b, sizeof b, "valve at %g V (its error value) while the controller was Pre-operational; %s runs after NMT start",
                  valve, control::toString(r.ctrl->kind()));
    row("controller 0x2010 = 1 (PI) in Pre-operational", kSdoOk, c, b);
  }
  return rows;
}

std::string guardTableMarkdown(const std::vector<GuardRow>& rows) {
  std::string s = "| SDO write to the running controller | expected | answer | what the loop saw |\n|---|---|---|---|\n";
  for (const auto& r : rows) {
    s += "| " + r.write + " | " + hexCode(r.expected) + " | " + hexCode(r.got) + (r.got == r.expected ? "" : " (UNEXPECTED)") +
         " | " + r.effect + " |\n";
  }
  return s;
}

}  // namespace pamc::nodes
