// Counts heap allocations around the 1 kHz cycle of every controller, the estimator and the
// emulator: the cycle must allocate nothing.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "control/controller.hpp"
#include "plant/plant.hpp"
#include "sim/trajectory.hpp"

#if defined(__SANITIZE_ADDRESS__)
#define PAMC_COUNT_ALLOCATIONS 0  // AddressSanitizer owns operator new; counting is for normal builds
#else
#define PAMC_COUNT_ALLOCATIONS 1
#endif

namespace {
std::atomic<long> g_allocs{0};
thread_local bool g_counting = false;

struct CountAllocations {
  CountAllocations() {
    g_allocs = 0;
    g_counting = true;
  }
  ~CountAllocations() { g_counting = false; }
  long count() const { return g_allocs.load(); }
};
}  // namespace

#if PAMC_COUNT_ALLOCATIONS
void* operator new(std::size_t n) {
  if (g_counting) ++g_allocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t n) {
  if (g_counting) ++g_allocs;
  if (void* p = std::malloc(n ? n : 1)) return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
#endif

using namespace pamc;

TEST(Allocation, CounterWorks) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  CountAllocations c;
  auto* v = new std::vector<int>(10);
  delete v;
  EXPECT_GE(c.count(), 2);
}

class AllocationFree : public ::testing::TestWithParam<control::Kind> {};

TEST_P(AllocationFree, TenThousandCyclesOnTheEmulator) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  control::ControllerConfig cfg;
  cfg.model = plant::PlantConfig::defaults().truth;  // any model with effects exercises the most code
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

INSTANTIATE_TEST_SUITE_P(Controllers, AllocationFree,
                         ::testing::Values(control::Kind::OpenLoop, control::Kind::PI, control::Kind::PidEso,
                                           control::Kind::PiAmc),
                         [](const auto& info) { return std::string(control::toString(info.param)); });

// The whole rig on the in-process bus - controller node (SYNC, RPDO latch, PI + AMC with a rolled-out
// prediction, setpoint TPDO, heartbeats, EMCY path), emulator nodes and physics - for 10 000 cycles.
#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"

TEST(Allocation, RigCyclesOnTheBusAllocateNothing) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  const std::string od = std::string(PAMC_SOURCE_DIR) + "/od/";
  nodes::ControllerNodeConfig c;
  c.eds_path = od + "controller.eds";
  c.kind = static_cast<int>(control::Kind::PiAmc);
  c.gains_from_config = true;
  c.ctrl.amc_horizon = 20;
  c.ctrl.amc_inverse = 0.2;
  c.ctrl.model = plant::PlantConfig::defaults().truth;
  c.has_trajectory = true;
  c.trajectory = sim::Trajectory::triangle(0.5, 5.0, 25.0);
  c.preroll_s = 0.2;
  nodes::EmulatorConfig e;
  e.sensor_eds = od + "sensor.eds";
  e.valve_eds = od + "valve.eds";
  e.payload_at_s = 5.0;
  canopen::VirtualBus bus;
  auto& cp = bus.addPort();
  auto& ep = bus.addPort();
  auto ctrl = std::make_unique<nodes::ControllerNode>(c, cp, [&bus] { return bus.now(); });
  auto emu = std::make_unique<nodes::EmulatorNodes>(e, ep);
  cp.setClient(&ctrl->node());
  ep.setClient(emu.get());
  emu->start(bus.now());
  ctrl->start(bus.now());
  nodes::CycleRecord r;
  bus.advanceBy(1'000'000);
  while (ctrl->records().pop(r)) {
  }
  long allocs = 0;
  {
    CountAllocations count;
    for (int k = 0; k < 10000; ++k) {
      bus.advanceBy(1000);
      while (ctrl->records().pop(r)) {
      }
    }
    allocs = count.count();
  }
  EXPECT_TRUE(ctrl->running());
  EXPECT_EQ(allocs, 0);
}
