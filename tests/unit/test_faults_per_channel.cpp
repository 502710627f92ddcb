// The fault table per channel (`pamc rig faults --rig od/rigs/four_muscles.ini --channel N`,
// docs/RELIABILITY.md "Faults per channel"): a few rows of the catalogue on the four-muscle rig. A fault
// of one channel's sensor must take that channel to its safe value as the one-muscle row does
// (tests/unit/test_faults.cpp, the same bounds) while the other three keep tracking; a fault of the valve
// module or of the SYNC, which every channel shares, must take every channel there and back.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "nodes/rig_file.hpp"
#include "rig/fault_rig.hpp"
#include "../common/fault_checks.hpp"

using namespace pamc;
using nodes::Fault;
using rig::BusFault;
using test::expectSafeAndBack;
using test::sent;
using test::tracksAsWithout;

namespace {

// The four-muscle rig with the faults of the sensor on channel (1-based).
rig::FaultRigOptions fourMuscles(std::size_t channel) {
  rig::FaultRigOptions o;
  o.od_dir = std::string(PAMC_SOURCE_DIR) + "/od";
  o.rig = nodes::readRigFile(o.od_dir + "/rigs/four_muscles.ini");
  o.channel = channel - 1;
  return o;
}

// The channels other than the row's: never safe, tracking through the fault and at the end as without it.
void expectOthersTrackOn(const rig::FaultRun& r) {
  ASSERT_EQ(r.channels.rmse_end.size(), 4u);
  for (std::size_t c = 0; c < 4; ++c) {
    if (c == r.channels.faulted) continue;
    SCOPED_TRACE("channel " + std::to_string(c + 1));
    EXPECT_EQ(r.channels.safe_cycles[c], 0u);
    EXPECT_TRUE(tracksAsWithout(r.channels.rmse_fault[c], r.channels.rmse_fault_base[c]))
        << r.channels.rmse_fault[c] << " mm during the fault (" << r.channels.rmse_fault_base[c] << ")";
    EXPECT_TRUE(tracksAsWithout(r.channels.rmse_end[c], r.channels.rmse_base[c]))
        << r.channels.rmse_end[c] << " mm at the end (" << r.channels.rmse_base[c] << ")";
  }
}

// Every channel safe for the fault's length and back to tracking as without it.
void expectEveryChannelSafeAndBack(const rig::FaultRun& r) {
  ASSERT_EQ(r.channels.rmse_end.size(), 4u);
  for (std::size_t c = 0; c < 4; ++c) {
    SCOPED_TRACE("channel " + std::to_string(c + 1));
    EXPECT_GT(r.channels.safe_cycles[c], 400u);
    EXPECT_TRUE(tracksAsWithout(r.channels.rmse_end[c], r.channels.rmse_base[c]))
        << r.channels.rmse_end[c] << " mm (" << r.channels.rmse_base[c] << ")";
  }
}

}  // namespace

TEST(FaultsPerChannel, ASilentSensorOfChannel3StopsChannel3Only) {
  const auto r = rig::runBusFault(BusFault::SensorSilentLong, fourMuscles(3));
  EXPECT_EQ(r.channels.faulted, 2u);
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_TRUE(sent(r, 0x8130));
  EXPECT_GE(r.fc.nmt_reboots, 1u);
  EXPECT_EQ(r.channels.emcy_named, std::vector<std::uint8_t>{3}) << "EMCYs naming channel 3 only";
  expectOthersTrackOn(r);
}

TEST(FaultsPerChannel, ABurstOfLostPdosOfChannel2StopsChannel2Only) {
  const auto r = rig::runBusFault(BusFault::PdoDropBurst, fourMuscles(2));
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_EQ(r.samples_lost, 10u);
  EXPECT_EQ(r.channels.emcy_named, std::vector<std::uint8_t>{2});
  expectOthersTrackOn(r);
}

TEST(FaultsPerChannel, ASilentValveModuleStopsEveryChannel) {
  const auto r = rig::runBusFault(BusFault::ValveSilentLong, fourMuscles(1));
  expectSafeAndBack(r, Fault::ValvePdoMissing, 0x8250, 5.0, 6.0);
  EXPECT_TRUE(sent(r, 0x8130));
  EXPECT_GE(r.fc.nmt_reboots, 1u);
  EXPECT_EQ(r.channels.emcy_named, (std::vector<std::uint8_t>{1, 2, 3, 4})) << "each channel's output lost";
  expectEveryChannelSafeAndBack(r);
}

// The recovery is a time, not a count of cycles: on the four-muscle rig at 100 Hz (as the VM's vcan
// run plays it) a valve module silent for 100 ms takes every channel back 0.5 s after its PDOs return
// (50 cycles), as at 1 kHz - not 500 cycles (5 s), longer than a short run. The PI, as in the VM: the
// AMC's model is the 1 kHz one.
TEST(FaultsPerChannel, AtTenMillisecondsTheRecoveryTakesHalfASecondAsAtOne) {
  auto o = fourMuscles(1);
  o.rig->period_us = 10000;
  o.kind = control::Kind::PI;
  const auto r = rig::runBusFault(BusFault::ValveSilentShort, o);
  EXPECT_EQ(r.first, Fault::ValvePdoMissing) << nodes::toString(r.first);
  EXPECT_TRUE(r.recovered);
  EXPECT_GE(r.resume_s, 0.5);
  EXPECT_LE(r.resume_s, 0.7);
  ASSERT_EQ(r.channels.safe_cycles.size(), 4u);
  for (std::size_t c = 0; c < 4; ++c) {
    EXPECT_GE(r.channels.safe_cycles[c], 50u) << "channel " << c + 1;
    EXPECT_LE(r.channels.safe_cycles[c], 70u) << "channel " << c + 1;
  }
}

TEST(FaultsPerChannel, AStoppedSyncStopsEveryChannelWithOneEmcy) {
  const auto r = rig::runBusFault(BusFault::SyncStop, fourMuscles(1));
  expectSafeAndBack(r, Fault::SyncLost, 0x8100, 1.5, 1.5);
  EXPECT_EQ(r.emcy, std::vector<std::uint16_t>{0x8100});
  EXPECT_EQ(r.channels.emcy_named.size(), 1u) << "a cause of the bus is reported once";
  expectEveryChannelSafeAndBack(r);
}

// Four channels recovering in one cycle send their EMCY error resets together; on the timed bus of the
// flood rows they must not crowd out the next cycle's SYNC and setpoints (the controller's EMCY inhibit
// time, 0x1015, spaces them): every channel safe for as long as the one-muscle row (200 cycles of
// flood, 500 to recover: 700), not a second overrun's 500 more.
TEST(FaultsPerChannel, TheErrorResetsOfFourChannelsDoNotCauseASecondOverrun) {
  const auto r = rig::runBusFault(BusFault::FloodFull, fourMuscles(1));
  expectSafeAndBack(r, Fault::CanOverrun, 0x8110, 1.0, 2.0);
  ASSERT_EQ(r.channels.safe_cycles.size(), 4u);
  for (std::size_t c = 0; c < 4; ++c) {
    SCOPED_TRACE("channel " + std::to_string(c + 1));
    EXPECT_LE(r.channels.safe_cycles[c], 750u);
  }
}

// Without a rig file the row is the one-muscle table's: one channel, the same figures as before.
TEST(FaultsPerChannel, WithoutARigFileTheTableHasOneChannel) {
  rig::FaultRigOptions o;
  o.od_dir = std::string(PAMC_SOURCE_DIR) + "/od";
  const auto r = rig::runBusFault(BusFault::PdoDropBurst, o);
  ASSERT_EQ(r.channels.rmse_end.size(), 1u);
  EXPECT_EQ(r.rmseEnd(), r.channels.rmse_end[0]);
  EXPECT_EQ(r.channels.emcy_named, std::vector<std::uint8_t>{0}) << "a node of one channel names none";
  const std::string table = rig::faultTableMarkdown({r});
  EXPECT_EQ(table.find("other channels"), std::string::npos) << table;
}
