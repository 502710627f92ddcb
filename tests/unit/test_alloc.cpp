// Counts heap allocations around the 1 kHz cycle of every controller, the estimator and the
// emulator: the cycle must allocate nothing.
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>

#include "control/controller.hpp"
#include "plant/plant.hpp"

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
