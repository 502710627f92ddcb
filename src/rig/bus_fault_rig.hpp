// The rig of the fault tools (fault table, soak, parameter guards): controller and emulator nodes on
// the in-process bus plus the stations a fault needs (a SYNC producer, a flooder, impostors on the
// controller's and the sensor's node-IDs), and the table of bus faults. Internal to src/rig.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <vector>

#include "canopen/bus.hpp"
#include "canopen/node.hpp"
#include "nodes/emulator_node.hpp"
#include "plant/plant.hpp"
#include "rig/fault_rig.hpp"
#include "rig/rig_emulator.hpp"

namespace pamc::rig::detail {

using canopen::Frame;
using canopen::TimeUs;
using canopen::VirtualBus;

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

inline Frame errorFrame(std::uint32_t cls, std::uint8_t d1) {
  Frame f;
  f.flags = canopen::kFrameError;
  f.id = cls;
  f.len = 8;
  f.data[1] = d1;
  return f;
}

struct Rig;

// One row per bus fault: what it is called, how long it lasts, what the rig needs for it, and how it
// is injected and cleared. Adding a fault: one enum value (fault_rig.hpp) and one row here.
// kAtStart: injected after the emulator's start, before the controller's (not into a running loop).
enum Needs : unsigned { kPlain = 0, kSyncSource = 1, kTimedBus = 2, kDupController = 4, kDupSensor = 8, kAtStart = 16 };
struct FaultSpec {
  BusFault fault;
  const char* name;         // for --only
  const char* description;  // for the table
  double seconds;           // how long it is injected
  unsigned needs;
  void (*begin)(Rig&);
  void (*end)(Rig&);
};
const FaultSpec& spec(BusFault f);
inline bool consumesSync(BusFault f) { return (spec(f).needs & kSyncSource) != 0; }
inline bool timedBus(BusFault f) { return (spec(f).needs & kTimedBus) != 0; }
inline double faultSeconds(BusFault f) { return spec(f).seconds; }
inline bool atStart(BusFault f) { return (spec(f).needs & kAtStart) != 0; }

// The controller of the fault tools: their controller and gains on a 0.2 Hz sine, in the built-in
// one-muscle layout or with the rig file's channels; consume: the SYNC of a separate producer.
inline nodes::ControllerNodeConfig faultRigController(const FaultRigOptions& o, bool consume) {
  nodes::ControllerNodeConfig c;
  c.eds_path = o.od_dir + "/controller.eds";
  if (o.rig) nodes::applyRig(*o.rig, c);
  c.kind = static_cast<int>(o.kind);
  c.gains_from_config = true;
  c.ctrl.kp = o.kp;
  c.ctrl.ki = o.ki;
  c.ctrl.kc = o.kc;
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::sine(0.2, 5.0, 15.0);
  c.preroll_s = o.preroll_s;
  c.produce_sync = !consume;
  return c;
}

// The emulator: pamc's own sensor and valve, or the rig file's devices (emulatorOf) with the sensor faults on
// the sensor of o.channel.
inline nodes::EmulatorConfig faultRigEmulator(const FaultRigOptions& o) {
  nodes::EmulatorConfig e;
  e.sensor_eds = o.od_dir + "/sensor.eds";
  e.valve_eds = o.od_dir + "/valve.eds";
  e.seed = o.seed;
  if (!o.rig) return e;
  e = emulatorOf(*o.rig, e);
  e.fault_channel = o.channel;
  return e;
}

// The whole rig of one run.
struct Rig {
  // f sets the rig up for that fault (SYNC source, timed bus, second node); nothing is injected yet.
  // soak: everything any fault needs at once - the controller consumes the SYNC of a separate producer,
  // the bus has 1 Mbit/s timing, a flooder and a second node with the controller's and with the faulted
  // sensor's node-ID are on it (all idle).
  Rig(BusFault f, const FaultRigOptions& o, bool soak = false)
      : bus(), cport(bus.addPort()), eport(bus.addPort()), aux(bus.addPort()) {
    const bool consume = soak || consumesSync(f);
    if (soak || timedBus(f)) bus.setBitrate(1'000'000, 32);
    const nodes::ControllerNodeConfig c = faultRigController(o, consume);
    traj = c.trajectory;
    channel = o.channel;
    sensor_id = o.rig ? o.rig->channels.at(o.channel).cfg.sensor_id : nodes::ChannelConfig{}.sensor_id;
    ctrl = std::make_unique<nodes::ControllerNode>(c, cport, [this] { return bus.now(); });
    emu = std::make_unique<nodes::EmulatorNodes>(faultRigEmulator(o), eport);
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
    if (soak || (spec(f).needs & kDupController)) {
      auto& p = bus.addPort();
      imp_ctrl = std::make_unique<Impostor>(p, ctrl->node().nodeId(), false);
      p.setClient(imp_ctrl.get());
    }
    if (soak || (spec(f).needs & kDupSensor)) {
      auto& p = bus.addPort();
      imp_sensor = std::make_unique<Impostor>(p, sensor_id, true);
      p.setClient(imp_sensor.get());
    }
    bus.addTap([this](const Frame& fr, TimeUs t) {
      if (fr.id != 0x81 || fr.len != 8 || fr.error()) return;
      ++emcy_frames;
      if (t < emcy_from) return;
      emcy.push_back(canopen::getU16(fr.data));
      emcy_channel.push_back(fr.data[5]);
    });
    emu->start(0);
    if (!atStart(f)) startController();
  }
  void startController() {
    ctrl->start(bus.now());
    if (sync) sync->start(bus.now());
  }
  // An expedited SDO download of 4 bytes to a node, from the rig's own port (answered at the next step).
  void sdoWrite32(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t v) {
    std::uint8_t d[8] = {0x23, static_cast<std::uint8_t>(index), static_cast<std::uint8_t>(index >> 8), sub};
    canopen::putU32(d + 4, v);
    aux.send(canopen::makeFrame(0x600u + node, 8, d));
  }
  void step(TimeUs dt) {
    bus.advanceBy(dt);
    nodes::CycleRecord r;
    while (ctrl->records().pop(r)) {
      recs.push_back(r);
      rec_us.push_back(bus.now());
    }
  }

  VirtualBus bus;
  VirtualBus::Port &cport, &eport, &aux;
  std::unique_ptr<nodes::ControllerNode> ctrl;
  std::unique_ptr<nodes::EmulatorNodes> emu;
  std::unique_ptr<SyncSource> sync;
  std::unique_ptr<Flooder> flood;
  std::unique_ptr<Impostor> imp_ctrl, imp_sensor;
  control::Trajectory traj;
  std::size_t channel = 0;     // whose sensor the sensor faults hit (0-based)
  std::uint8_t sensor_id = 2;  // ... its node-ID
  std::vector<nodes::CycleRecord> recs;
  std::vector<TimeUs> rec_us;
  std::vector<std::uint16_t> emcy;
  std::vector<std::uint8_t> emcy_channel;  // the channel each names (1-based; byte 5)
  std::uint64_t emcy_frames = 0;
  TimeUs emcy_from = canopen::kNever;
};

void begin(Rig& r, BusFault f);
void end(Rig& r, BusFault f);

}  // namespace pamc::rig::detail
