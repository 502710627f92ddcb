// The checks a row of the fault table must pass (tests/unit/test_faults.cpp, one muscle;
// tests/unit/test_faults_per_channel.cpp, the row's channel of four): a safety fault, the valve safe in
// time, its EMCY on the bus, then the return.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>

#include "rig/fault_rig.hpp"

namespace pamc::test {

inline bool sent(const rig::FaultRun& r, std::uint16_t code) {
  return std::find(r.emcy.begin(), r.emcy.end(), code) != r.emcy.end();
}

// Normal operation's largest command step is ~0.002 V per cycle. The return after a fault is
// rate-limited to 0.02 V per cycle while the setpoint ramps back (ControllerNodeConfig::ramp_slew_v);
// the restarted AMC estimator's transient after that stays below 0.1 V per cycle.
constexpr double kStepBound = 0.1;

// Tracking back to the reference run's within 20 % + 0.02 mm.
inline bool tracksAsWithout(double rmse, double base) { return rmse <= 1.2 * base + 0.02; }

// A safety fault, the valve safe within max_safe cycles, its EMCY, then recovery.
inline void expectSafeAndBack(const rig::FaultRun& r, nodes::Fault first, std::uint16_t code, double max_detect,
                              double max_safe) {
  SCOPED_TRACE(rig::busFaultDescription(r.fault));
  EXPECT_EQ(r.first, first) << nodes::toString(r.first);
  EXPECT_GE(r.detect_cycles, 0.0);
  EXPECT_LE(r.detect_cycles, max_detect);
  EXPECT_GE(r.safe_cycles, 0.0);
  EXPECT_LE(r.safe_cycles, max_safe);
  EXPECT_TRUE(sent(r, code)) << "EMCY 0x" << std::hex << code << " not on the bus";
  EXPECT_TRUE(r.emcy_reset) << "no EMCY error reset after recovery";
  EXPECT_TRUE(r.recovered);
  EXPECT_GE(r.resume_s, 0.0);
  EXPECT_LE(r.resume_s, 0.7);  // 500 clean cycles after the cause is gone (plus a re-boot)
  EXPECT_LE(r.max_step_v, kStepBound);
  EXPECT_TRUE(tracksAsWithout(r.rmseEnd(), r.rmseBase()))
      << r.rmseEnd() << " mm: tracking error not back to normal (" << r.rmseBase() << ")";
  EXPECT_GT(r.safeCyclesTotal(), 400u);
}

}  // namespace pamc::test
