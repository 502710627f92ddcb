// Counts heap allocations around the 1 kHz cycle of every controller, the estimator and the
// emulator: the cycle must allocate nothing.
#include <gtest/gtest.h>

#include <cmath>

#include "../common/count_allocations.hpp"
#include "control/controller.hpp"
#include "plant/plant.hpp"
#include "control/trajectory.hpp"

using pamc::test::CountAllocations;

using namespace pamc;

TEST(Allocation, CounterWorks) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  CountAllocations c;
  static std::vector<int>* volatile v = nullptr;  // so the pair is not elided
  v = new std::vector<int>(10);
  delete v;
  EXPECT_GE(c.count(), 2);
  struct alignas(64) Wide {
    double x[8];
  };
  const long before = c.count();
  static Wide* volatile keep = nullptr;  // so the pair is not elided
  keep = new Wide{};
  delete keep;
  EXPECT_EQ(c.count(), before + 1) << "the aligned operator new is counted too";
}

class AllocationFree : public ::testing::TestWithParam<control::Kind> {};

TEST_P(AllocationFree, TenThousandCyclesOnTheEmulator) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  control::ControllerConfig cfg;
  cfg.model = plant::PlantConfig::modelDefaults().truth;  // any model with effects exercises the most code
  auto ctrl = control::makeController(GetParam(), cfg);
  plant::Plant plant;  // default: every effect on
  plant.reset(0.0);
  ctrl->activate(0.0, plant.measure());
  long allocs = 0;
  {
    CountAllocations c;
    for (int k = 0; k < 10000; ++k) {
      const double t = k * 1e-3;
      const double yd = 15 + 10 * std::sin(2 * M_PI * 0.5 * t);
      const auto o = ctrl->update(yd, yd, plant.measure());
      plant.step(o.u, k > 5000 ? 40.0 : 0.0);
    }
    allocs = c.count();
  }
  EXPECT_EQ(allocs, 0) << control::toString(GetParam());
}

namespace {
// Allocations in 10000 cycles of the AMC configured by cfg (its model: the plant's truth) on the plant
// pc, a 0.5 Hz sine to track and, with `payload`, 40 N hung on halfway.
long amcCycleAllocations(control::ControllerConfig cfg, const plant::PlantConfig& pc, bool payload) {
  cfg.model = pc.truth;
  auto ctrl = control::makeController(control::Kind::PiAmc, cfg);
  plant::Plant plant(pc);
  plant.reset(0.0);
  ctrl->activate(0.0, plant.measure());
  CountAllocations c;
  for (int k = 0; k < 10000; ++k) {
    const double yd = 15 + 10 * std::sin(2 * M_PI * 0.5 * k * 1e-3);
    const auto o = ctrl->update(yd, yd, plant.measure());
    plant.step(o.u, payload && k > 5000 ? 40.0 : 0.0);
  }
  return c.count();
}
}  // namespace

// The AMC and the emulator with the payload's friction inside its force balance (force_loop).
TEST(Allocation, ForceLoopCyclesAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const auto pc = plant::PlantConfig::fromJson(
      nlohmann::json::parse(
          R"({"kind":"model","effects":{"mass_spring":{"enabled":false},"force_loop":{"enabled":true,"zmax":0.6}}})"),
      "test");
  EXPECT_EQ(amcCycleAllocations({}, pc, true), 0);
}

// The paper's AMC read bus-aware (the posterior rolled through the commands in flight) on the emulator.
TEST(Allocation, BusAwareAmcCyclesAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  control::ControllerConfig cfg;
  cfg.amc_bus_aware = true;
  EXPECT_EQ(amcCycleAllocations(cfg, plant::PlantConfig::modelDefaults(), false), 0);
}

INSTANTIATE_TEST_SUITE_P(Controllers, AllocationFree,
                         ::testing::Values(control::Kind::OpenLoop, control::Kind::PI, control::Kind::PidEso,
                                           control::Kind::PiAmc, control::Kind::Input, control::Kind::Mbc),
                         [](const auto& info) { return std::string(control::toString(info.param)); });

// The whole rig on the in-process bus - controller node (SYNC, RPDO latch, PI + AMC with a rolled-out
// prediction, setpoint TPDO, heartbeats, EMCY path), emulator nodes and physics - for 10 000 cycles.
#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"
#include "nodes/rig_file.hpp"
#include "rig/rig_emulator.hpp"
#include "rig/virtual_rig.hpp"

namespace {

// The in-process rig with its emulator; the sensor falls silent for 0.2 s at 4 s (position missing,
// heartbeat lost, safe state), comes back, and the loop recovers.
nodes::EmulatorConfig emulatorWithSilentSensor(const std::string& od) {
  nodes::EmulatorConfig e;
  e.sensor_eds = od + "sensor.eds";
  e.valve_eds = od + "valve.eds";
  e.sensor_silent_at_s = 4.0;
  e.sensor_silent_for_s = 0.2;
  return e;
}

// Heap allocations over 10 s of the rig's cycles, after 1 s to settle; the rig ran its fault path.
long rigAllocations(const nodes::ControllerNodeConfig& c, const nodes::EmulatorConfig& e) {
  rig::VirtualRig rig(c, e);
  rig.setRecordSink([](const nodes::CycleRecord&) {});  // drained, not kept
  rig.start();
  rig.runFor(1.0);
  long allocs = 0;
  {
    CountAllocations count;
    rig.runFor(10.0);
    allocs = count.count();
  }
  EXPECT_TRUE(rig.controller().running());
  EXPECT_GE(rig.controller().faultCounters().episodes, 1u) << "the fault path ran inside the counted window";
  EXPECT_GE(rig.controller().faultCounters().recoveries, 1u);
  return allocs;
}

}  // namespace

TEST(Allocation, RigCyclesOnTheBusAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const std::string od = std::string(PAMC_SOURCE_DIR) + "/od/";
  nodes::ControllerNodeConfig c;
  c.eds_path = od + "controller.eds";
  c.kind = static_cast<int>(control::Kind::PiAmc);
  c.gains_from_config = true;
  c.ctrl.amc_horizon = 20;
  c.ctrl.amc_inverse = 0.2;
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::triangle(0.5, 5.0, 25.0);
  c.preroll_s = 0.2;
  auto e = emulatorWithSilentSensor(od);
  e.payload.at_s = 5.0;
  EXPECT_EQ(rigAllocations(c, e), 0);
}

// Four channels on one node (od/rigs/four_muscles.ini), channel 2's sensor silent for a while: its fault
// path and the others' cycles - nothing allocated.
TEST(Allocation, FourChannelCyclesAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const std::string od = std::string(PAMC_SOURCE_DIR) + "/od/";
  const auto rf = nodes::readRigFile(od + "rigs/four_muscles.ini");
  nodes::ControllerNodeConfig c;
  nodes::applyRig(rf, c);
  c.kind = static_cast<int>(control::Kind::PiAmc);
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::triangle(0.5, 5.0, 25.0);
  c.preroll_s = 0.2;
  auto e = rig::emulatorOf(rf, emulatorWithSilentSensor(od));
  e.fault_channel = 1;
  EXPECT_EQ(rigAllocations(c, e), 0);
}

// --input on the rig: the multisine's table read each cycle, the command passed through, a fault
// episode and the recovery's ramp from the command in effect - nothing allocated.
TEST(Allocation, RigInputCyclesAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const std::string od = std::string(PAMC_SOURCE_DIR) + "/od/";
  nodes::ControllerNodeConfig c;
  c.eds_path = od + "controller.eds";
  c.kind = static_cast<int>(control::Kind::Input);
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::parse("multisine:1:0.1:5:-3:3");
  c.preroll_s = 0.2;
  EXPECT_EQ(rigAllocations(c, emulatorWithSilentSensor(od)), 0);
}

// The AMC whose model ends in the muscle's whole-stroke force balance (muscle_balance, its stops and
// friction elements in use).
TEST(Allocation, MuscleBalanceCyclesAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  control::ControllerConfig cfg;
  cfg.model = model::Model({7.5, 1.0, 24.0, 1.0, 0.3, 0.3});
  cfg.model.addEffect("muscle_balance");
  for (const auto& [k, v] : {std::pair{"a1", -0.012}, {"zp", 0.05}, {"spread", 4.0}, {"lo", 0.0}, {"hi", 38.0}})
    cfg.model.setEffectParam("muscle_balance", k, v);
  auto ctrl = control::makeController(control::Kind::PiAmc, cfg);
  ctrl->activate(0.0, 20.0);
  long allocs = 0;
  double y = 20.0;
  {
    CountAllocations c;
    for (int k = 0; k < 10000; ++k) {
      const double yd = 18 + 15 * std::sin(2 * M_PI * 0.5 * k * 1e-3);
      const auto o = ctrl->update(yd, yd, y);
      y += 0.05 * (20.0 + 5.0 * o.u - y);
    }
    allocs = c.count();
  }
  EXPECT_EQ(allocs, 0);
}
