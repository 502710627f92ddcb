// Parameters over SDO: writes the running controller must refuse (read-only, out of range, a
// controller switch or the cycle's wiring while Operational, an unstable model), and the staging of
// a parameter set: written entries do not reach the loop until a commit (0x2003:01 = 1), which the
// loop takes at the next SYNC with bumpless transfer, allocating nothing in the cycle.
#include <gtest/gtest.h>

#include <malloc.h>

#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <chrono>
#include <thread>

#include "canopen/bus.hpp"
#include "canopen/node.hpp"
#include "nodes/controller_parameters.hpp"
#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"
#include "nodes/process_data.hpp"
#include "rig/virtual_rig.hpp"
#include "rig/fault_rig.hpp"
#include "plant/plant.hpp"

using namespace pamc;
using canopen::Frame;

namespace {
const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

nodes::ControllerNodeConfig controllerConfig() {
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "controller.eds";
  c.kind = static_cast<int>(control::Kind::PiAmc);
  c.gains_from_config = true;
  c.ctrl.ki = 1.5;
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::sine(0.2, 5.0, 15.0);
  c.preroll_s = 1.0;
  return c;
}

// Controller and emulator on the in-process bus, and a raw port for SDO requests and NMT commands.
nodes::EmulatorConfig emulatorConfig() {
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  return e;
}
nodes::ControllerNodeConfig withOffCycle(nodes::ControllerNodeConfig c, bool off_cycle) {
  c.build_off_cycle = off_cycle;
  return c;
}

nodes::ControllerNodeConfig controllerConfig(control::Kind kind) {
  auto c = controllerConfig();
  c.kind = static_cast<int>(kind);
  return c;
}

struct Rig {
  explicit Rig(control::Kind kind = control::Kind::PiAmc, bool off_cycle = false)
      : rig(withOffCycle(controllerConfig(kind), off_cycle), emulatorConfig()),
        bus(rig.bus()),
        tool(rig.addPort()),
        ctrl(&rig.controller()),
        emu(&rig.emulator()),
        recs(rig.records()) {
    rig.addTap([this](const Frame& f, canopen::TimeUs) {
      if (f.id == 0x581) last = f, answered = true;
      if (f.id == 0x81 && f.len == 8) emcy.push_back(canopen::getU16(f.data));
    });
    rig.start();
    recs.reserve(20000);
  }
  void cycle() { rig.step(); }
  void runTo(double t) {
    while (ctrl->runTime() < t) cycle();
  }
  // One SDO frame, answered at the same instant on the ideal bus.
  std::uint32_t request(const std::uint8_t (&b)[8]) {
    answered = false;
    tool.send(canopen::makeFrame(0x601, 8, b));
    bus.flush();
    EXPECT_TRUE(answered);
    return last.data[0] == 0x80 ? canopen::getU32(last.data + 4) : 0;
  }
  std::uint32_t writeU8(std::uint16_t idx, std::uint8_t sub, std::uint8_t v) {
    const std::uint8_t b[8] = {0x2F, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, v, 0, 0,
                               0};
    return request(b);
  }
  // Segmented download of a REAL64, with `cycles` SYNC cycles between the two segments.
  std::uint32_t writeDouble(std::uint16_t idx, std::uint8_t sub, double v, int cycles = 0) {
    std::uint8_t d[8];
    std::memcpy(d, &v, 8);
    const std::uint8_t init[8] = {
        0x21, static_cast<std::uint8_t>(idx), static_cast<std::uint8_t>(idx >> 8), sub, 8, 0, 0, 0};
    if (auto c = request(init)) return c;
    const std::uint8_t s1[8] = {0x00, d[0], d[1], d[2], d[3], d[4], d[5], d[6]};
    if (auto c = request(s1)) return c;
    for (int k = 0; k < cycles; ++k) cycle();
    const std::uint8_t s2[8] = {0x1D, d[7], 0, 0, 0, 0, 0, 0};
    return request(s2);
  }
  void nmt(std::uint8_t cmd) {
    const std::uint8_t b[2] = {cmd, 1};
    tool.send(canopen::makeFrame(0x000, 2, b));
    bus.flush();
  }

  rig::VirtualRig rig;
  canopen::VirtualBus& bus;
  canopen::VirtualBus::Port& tool;
  nodes::ControllerNode* ctrl;
  nodes::EmulatorNodes* emu;
  std::vector<nodes::CycleRecord>& recs;
  std::vector<std::uint16_t> emcy;
  Frame last;
  bool answered = false;
};
}  // namespace

// The table of docs/RELIABILITY.md ("Parameters over SDO"): every write answered as expected, and
// the loop's parameter set changed only by the commit.
TEST(SdoGuards, EveryWriteGetsTheExpectedAnswer) {
  rig::FaultRigOptions o;
  o.od_dir = kOd;
  const auto rows = rig::runParameterGuards(o);
  ASSERT_GE(rows.size(), 20u);
  for (const auto& r : rows) {
    EXPECT_EQ(r.got, r.expected) << r.write;
    EXPECT_EQ(r.effect.find("CHANGED"), std::string::npos) << r.write << ": " << r.effect;
  }
}

TEST(SdoGuards, StagedValuesNeverReachTheLoopUntilTheCommit) {
  // Two identical rigs; one gets a new parameter set written over SDO, value by value, with SYNC
  // cycles between the values and between the segments of each value.
  Rig a, b;
  a.runTo(2.0);
  b.runTo(2.0);
  ASSERT_EQ(a.recs.size(), b.recs.size());
  EXPECT_EQ(b.writeDouble(0x2000, 1, 0.12, 2), 0u);                        // kp
  EXPECT_EQ(b.ctrl->node().od().entry(0x2003, 2).get<std::uint8_t>(), 1);  // staged
  for (int k = 0; k < 2; ++k) a.cycle();
  for (int k = 0; k < 5; ++k) a.cycle(), b.cycle();
  EXPECT_EQ(b.writeDouble(0x2000, 2, 1.8, 3), 0u);  // ki
  for (int k = 0; k < 3; ++k) a.cycle();
  EXPECT_EQ(b.writeDouble(0x2001, 6, -0.5, 1), 0u);  // gamma: with it the model is unstable
  a.cycle();
  for (int k = 0; k < 200; ++k) a.cycle(), b.cycle();
  // Half-written, and even unstable: the loop ran exactly as without the writes.
  ASSERT_EQ(a.recs.size(), b.recs.size());
  for (std::size_t i = 0; i < a.recs.size(); ++i) {
    ASSERT_EQ(a.recs[i].u, b.recs[i].u) << "cycle " << i;
    ASSERT_EQ(a.recs[i].y, b.recs[i].y) << "cycle " << i;
  }
  EXPECT_EQ(b.ctrl->activeParameters().kp, a.ctrl->activeParameters().kp);
  // A commit of the set with the unstable model is refused; nothing changes.
  EXPECT_EQ(b.writeU8(0x2003, 1, 1), canopen::kAbortParameterIncompatible);
  a.cycle(), b.cycle();
  EXPECT_EQ(a.recs.back().u, b.recs.back().u);
  // Restore gamma, commit: the loop takes the set at the next SYNC.
  const double gamma = a.ctrl->activeParameters().model.core().gamma;
  EXPECT_EQ(b.writeDouble(0x2001, 6, gamma), 0u);
  EXPECT_EQ(b.writeU8(0x2003, 1, 1), 0u);
  EXPECT_EQ(b.ctrl->activeParameters().kp, a.ctrl->activeParameters().kp);  // not before the cycle boundary
  EXPECT_EQ(b.ctrl->node().od().entry(0x2003, 2).get<std::uint8_t>(), 0);
  const std::size_t n = b.recs.size();
  a.cycle(), b.cycle();
  EXPECT_EQ(b.ctrl->activeParameters().kp, 0.12);
  EXPECT_EQ(b.ctrl->activeParameters().ki, 1.8);
  ASSERT_EQ(b.recs.size(), n + 1);
  // Bumpless: the first command of the new set continues from the last one.
  EXPECT_LE(std::fabs(b.recs[n].u - b.recs[n - 1].u), 0.02 + 1e-9);
  for (int k = 0; k < 3000; ++k) b.cycle();
  double worst = 0;
  for (std::size_t i = n; i < b.recs.size(); ++i) worst = std::max(worst, std::fabs(b.recs[i].u - b.recs[i - 1].u));
  // The AMC's estimator restarts with the new set; its transient stays within 0.1 V per cycle
  // (measured 0.005 V; normal tracking ~0.002 V; a restart from rest without the ramp: 2.3 V).
  EXPECT_LE(worst, 0.1);
  EXPECT_EQ(b.ctrl->fault(), nodes::Fault::None);
  EXPECT_TRUE(b.emcy.empty());
}

TEST(SdoGuards, ACommittedPiSetIsBumpless) {
  Rig r(control::Kind::PI);
  r.runTo(2.0);
  EXPECT_EQ(r.writeDouble(0x2000, 1, 0.15), 0u);
  EXPECT_EQ(r.writeDouble(0x2000, 2, 2.5), 0u);
  double before = 0;
  for (std::size_t i = r.recs.size() - 1000; i < r.recs.size(); ++i)
    before = std::max(before, std::fabs(r.recs[i].u - r.recs[i - 1].u));
  EXPECT_EQ(r.writeU8(0x2003, 1, 1), 0u);
  const std::size_t n = r.recs.size();
  for (int k = 0; k < 3000; ++k) r.cycle();
  EXPECT_EQ(r.ctrl->activeParameters().ki, 2.5);
  double worst = 0;
  for (std::size_t i = n; i < r.recs.size(); ++i) worst = std::max(worst, std::fabs(r.recs[i].u - r.recs[i - 1].u));
  // The integrator takes over the last command and the setpoint ramps from the position: the
  // command moves no faster than in normal tracking.
  EXPECT_LE(worst, 2.0 * before + 1e-3) << "before " << before;
}

TEST(SdoGuards, TheCycleThatTakesACommitAllocatesAndFreesNothing) {
  Rig r;
  r.runTo(2.0);
  EXPECT_EQ(r.writeDouble(0x2000, 1, 0.2), 0u);
  EXPECT_EQ(r.writeU8(0x2003, 1, 1), 0u);  // checked and built here, in the SDO server
  const auto before = mallinfo2().uordblks;
  r.bus.advanceBy(1000);  // the SYNC that swaps the sets (records stay in the ring)
  const auto after = mallinfo2().uordblks;
  EXPECT_EQ(r.ctrl->activeParameters().kp, 0.2);
  EXPECT_EQ(after, before);
  // The replaced controller is freed by the next commit, outside the cycle.
  EXPECT_EQ(r.writeDouble(0x2000, 1, 0.25), 0u);
  EXPECT_EQ(r.writeU8(0x2003, 1, 1), 0u);
  const auto before2 = mallinfo2().uordblks;
  r.bus.advanceBy(1000);
  EXPECT_EQ(mallinfo2().uordblks, before2);
  EXPECT_EQ(r.ctrl->activeParameters().kp, 0.25);
}

// On a rig the controller of a commit is built on a worker thread: the SDO answer does not wait for
// it, and the cycle that takes it (at a boundary, once built) still allocates and frees nothing. The
// open loop's inverse characteristic is the slow build.
TEST(SdoGuards, AControllerBuiltOffTheCycleIsTakenAtACycleBoundary) {
  for (auto kind : {control::Kind::PiAmc, control::Kind::OpenLoop}) {
    Rig r(kind, true);
    r.runTo(2.0);
    const std::uint64_t applied = r.ctrl->faultCounters().sets_applied;
    EXPECT_EQ(r.writeDouble(0x2020, 0, 1.5), 0u);  // the safe value: used by every controller
    EXPECT_EQ(r.writeU8(0x2003, 1, 1), 0u);        // answered at once; the worker builds
    // Virtual time stands still while the worker runs; give it up to 5 s of wall time.
    for (int i = 0; i < 500 && r.ctrl->faultCounters().sets_applied == applied; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
      const auto before = mallinfo2().uordblks;
      r.bus.advanceBy(1000);
      if (r.ctrl->faultCounters().sets_applied != applied) {
        EXPECT_EQ(mallinfo2().uordblks, before) << "the cycle that took the set allocated";
      }
    }
    EXPECT_EQ(r.ctrl->faultCounters().sets_applied, applied + 1) << control::toString(kind);
    EXPECT_DOUBLE_EQ(r.ctrl->safeCommand(), nodes::pd::commandFromVolts(1.5));
    // A bad set is still refused in the SDO answer, before any build.
    EXPECT_EQ(r.writeDouble(0x2001, 6, -0.5), 0u);  // gamma: with it the model is unstable
    EXPECT_EQ(r.writeU8(0x2003, 1, 1), canopen::kAbortParameterIncompatible);
    r.runTo(r.ctrl->runTime() + 0.5);
    EXPECT_EQ(r.ctrl->fault(), nodes::Fault::None);
  }
}

TEST(SdoGuards, ACommittedSafeValueBecomesTheValvesErrorValue) {
  Rig r;
  r.runTo(1.0);
  auto& err = r.emu->valve().od().entry(0x6444, 1);
  EXPECT_EQ(err.get<std::int32_t>(), 0);  // 0 V, written in the valve's boot
  EXPECT_EQ(r.writeDouble(0x2020, 0, 2.0), 0u);
  EXPECT_EQ(r.writeU8(0x2003, 1, 1), 0u);
  for (int k = 0; k < 5; ++k) r.cycle();
  EXPECT_EQ(r.ctrl->safeCommand(), -3.0);
  EXPECT_EQ(err.get<std::int32_t>(), 6553);  // 2 V of 0..32767 = 0..10 V
  EXPECT_EQ(r.ctrl->faultCounters().valve_sdo_errors, 0u);
  // The valve uses it: controller to Pre-operational, valve to its error value.
  r.nmt(0x80);
  for (int k = 0; k < 3; ++k) r.cycle();
  EXPECT_NEAR(r.emu->valveVolts(), 2.0, 1e-3);
}

TEST(SdoGuards, ControllerSwitchOnlyThroughPreOperational) {
  Rig r;
  r.runTo(1.5);
  EXPECT_EQ(r.writeU8(0x2010, 0, 1), canopen::kAbortDeviceState);
  EXPECT_EQ(r.ctrl->kind(), control::Kind::PiAmc);
  r.nmt(0x80);  // controller to Pre-operational: the valve goes to its error value
  for (int k = 0; k < 3; ++k) r.cycle();
  EXPECT_EQ(r.emu->valveVolts(), 0.0);
  EXPECT_TRUE(r.emu->valveInError());
  EXPECT_EQ(r.writeU8(0x2010, 0, 1), 0u);
  EXPECT_EQ(r.ctrl->kind(), control::Kind::PiAmc);  // stored, not used yet
  r.nmt(0x01);
  EXPECT_EQ(r.ctrl->kind(), control::Kind::PI);
  r.runTo(1.0);
  EXPECT_TRUE(r.ctrl->running());
  EXPECT_FALSE(r.emu->valveInError());
}

TEST(SdoGuards, AnUnstableSetAtNmtStartKeepsTheRunningController) {
  Rig r;
  r.runTo(1.5);
  r.nmt(0x80);
  EXPECT_EQ(r.writeDouble(0x2001, 5, -0.4), 0u);  // beta: beta + gamma < 0
  r.nmt(0x01);
  for (int k = 0; k < 5; ++k) r.cycle();
  EXPECT_EQ(r.ctrl->activeParameters().model.core().beta, plant::PlantConfig::modelDefaults().truth.core().beta);
  EXPECT_EQ(r.ctrl->faultCounters().sets_refused, 1u);
  EXPECT_NE(std::find(r.emcy.begin(), r.emcy.end(), 0x6100), r.emcy.end());
}

TEST(SdoGuards, CommandLineValuesMeetTheSameRules) {
  auto c = controllerConfig();
  c.ctrl.kp = 50.0;  // above 10 V/mm
  canopen::VirtualBus bus;
  auto& port = bus.addPort();
  try {
    nodes::ControllerNode node(c, port, [] { return canopen::TimeUs{0}; });
    FAIL() << "kp 50 accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("0x2000:01"), std::string::npos) << e.what();
  }
  c = controllerConfig();
  c.ctrl.model.core().gamma = -1.0;
  EXPECT_THROW(nodes::ControllerNode(c, port, [] { return canopen::TimeUs{0}; }), std::invalid_argument);
}

// The dictionary's defaults of the gain objects (0x2000) are the controllers' defaults
// (control::ControllerConfig, its gains control::kDefaultGains): a node that boots on od/controller.eds
// without a gain override runs what `pamc experiments` and the fault tools run.
TEST(ControllerDictionary, GainDefaultsAreTheControllersDefaults) {
  canopen::VirtualBus bus;
  auto& port = bus.addPort();
  auto node = canopen::Node::fromEds(kOd + "controller.eds", port);
  control::ControllerConfig other;  // a base unlike the defaults: what read() returns is the dictionary's
  other.kp = other.ki = other.kc = other.eso.beta1 = other.eso.beta2 = other.eso.beta3 = -1.0;
  other.eso.delta = other.eso.b0 = other.eso.gain = other.eso.tau = other.eso.wo = -1.0;
  other.eso.order = 0;
  const auto eds = nodes::ControllerParameters(*node, other).read().ctrl;
  const control::ControllerConfig d;
  EXPECT_EQ(d.kp, control::kDefaultGains.kp);
  EXPECT_EQ(d.ki, control::kDefaultGains.ki);
  EXPECT_EQ(d.kc, control::kDefaultGains.kc);
  EXPECT_EQ(eds.kp, d.kp) << "0x2000:01";
  EXPECT_EQ(eds.ki, d.ki) << "0x2000:02";
  EXPECT_EQ(eds.kc, d.kc) << "0x2000:03";
  EXPECT_EQ(eds.eso.beta1, d.eso.beta1) << "0x2000:04";
  EXPECT_EQ(eds.eso.beta2, d.eso.beta2) << "0x2000:05";
  EXPECT_EQ(eds.eso.beta3, d.eso.beta3) << "0x2000:06";
  EXPECT_EQ(eds.eso.delta, d.eso.delta) << "0x2000:07";
  EXPECT_EQ(eds.eso.b0, d.eso.b0) << "0x2000:08";
  EXPECT_EQ(eds.eso.gain, d.eso.gain) << "0x2000:09";
  EXPECT_EQ(eds.eso.tau, d.eso.tau) << "0x2000:0A";
  EXPECT_EQ(eds.eso.wo, d.eso.wo) << "0x2000:0B";
  EXPECT_EQ(eds.eso.order, d.eso.order) << "0x2000:0C";
}
