// Faults on the bus, one per test, on the in-process rig (src/nodes/fault_rig.*): each injects the
// fault with the rig's fixed seed after 3 s of a 0.2 Hz sine, measures the cycles until the
// controller reacts and until the valve outputs its safe value, checks the EMCY codes on the bus,
// clears the fault and checks the recovery (EMCY reset, tracking error back to that of the run
// without the fault, no output step beyond the bumpless bound). The figures of docs/RELIABILITY.md
// come from the same runs (`pamc rig --faults`).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "canopen/bus.hpp"
#include "canopen/eds.hpp"
#include "canopen/node.hpp"
#include "rig/fault_rig.hpp"
#include "rig/bus_fault_rig.hpp"
#include "../common/fault_checks.hpp"

#include <cstring>

using namespace pamc;
using nodes::Fault;
using rig::BusFault;
using test::expectSafeAndBack;
using test::kStepBound;
using test::sent;

namespace {

rig::FaultRigOptions options() {
  rig::FaultRigOptions o;
  o.od_dir = std::string(PAMC_SOURCE_DIR) + "/od";
  return o;
}

// Faults the loop rides through: no safe state, no jump, tracking as without the fault.
void expectRideThrough(const rig::FaultRun& r) {
  SCOPED_TRACE(rig::busFaultDescription(r.fault));
  EXPECT_EQ(r.first, Fault::None) << nodes::toString(r.first);
  EXPECT_EQ(r.safeCyclesTotal(), 0u);
  EXPECT_TRUE(r.recovered);
  EXPECT_LE(r.max_step_v, kStepBound);
  EXPECT_LE(r.rmseEnd(), 1.2 * r.rmseBase() + 0.02);
}

}  // namespace

TEST(Faults, SensorSilentShortIsAMissingPositionAndResumesWithoutReboot) {
  const auto r = rig::runBusFault(BusFault::SensorSilentShort, options());
  // The 4th SYNC without a position (0x2021 = 3) raises the fault, the valve applies it one SYNC later.
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_EQ(r.emcy, std::vector<std::uint16_t>{0x8250});  // shorter than the 250 ms heartbeat time
  EXPECT_EQ(r.fc.nmt_reboots, 0u);
  EXPECT_EQ(r.samples_lost, 100u);
}

TEST(Faults, SensorSilentLongLosesTheHeartbeatAndIsRebootedWhenBack) {
  const auto r = rig::runBusFault(BusFault::SensorSilentLong, options());
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_TRUE(sent(r, 0x8130));
  // Back after the heartbeat timeout: NMT reset communication, boot-up, NMT start.
  EXPECT_GE(r.fc.nmt_reboots, 1u);
  EXPECT_GE(r.fc.nmt_starts, 3u);  // sensor and valve at start-up, the sensor again after its boot-up
}

TEST(Faults, SensorRebootIsStartedAgainByTheMaster) {
  const auto r = rig::runBusFault(BusFault::SensorReboot, options());
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_TRUE(sent(r, 0x8130));  // the boot-up of a monitored node (remote reset)
  EXPECT_EQ(r.fc.nmt_reboots, 0u);
  EXPECT_GE(r.fc.nmt_starts, 3u);
  EXPECT_LE(r.samples_lost, 55u);
}

TEST(Faults, PdosAfterTheSynchronousWindowAreDiscarded) {
  const auto r = rig::runBusFault(BusFault::PdoLateInCycle, options());
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_GE(r.counters.rpdo_late, 190u);
}

TEST(Faults, PdosOneCycleLateAreNotDetectedAndCostOneCycleOfDelay) {
  const auto r = rig::runBusFault(BusFault::PdoLateCycle, options());
  expectRideThrough(r);
  EXPECT_TRUE(r.emcy.empty());
  EXPECT_LE(r.samples_lost, 3u);  // the first cycle (nothing arrives) and the last (two arrive: conflict)
}

TEST(Faults, RandomPdoLossIsBridged) {
  const auto r = rig::runBusFault(BusFault::PdoDropRandom, options());
  expectRideThrough(r);
  EXPECT_TRUE(r.emcy.empty());
  EXPECT_GT(r.samples_lost, 50u);  // 5 % of 2000
  EXPECT_LT(r.samples_lost, 200u);
}

TEST(Faults, ABurstOfLostPdosIsAMissingPosition) {
  const auto r = rig::runBusFault(BusFault::PdoDropBurst, options());
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 5.0, 6.0);
  EXPECT_EQ(r.samples_lost, 10u);
}

TEST(Faults, DuplicatedPdosAreIgnored) {
  const auto r = rig::runBusFault(BusFault::PdoDuplicate, options());
  expectRideThrough(r);
  EXPECT_TRUE(r.emcy.empty());
  EXPECT_GE(r.counters.rpdo_duplicates, 1990u);
  EXPECT_EQ(r.samples_lost, 0u);
}

TEST(Faults, SyncStopIsDetectedWithinOneAndAHalfPeriods) {
  const auto r = rig::runBusFault(BusFault::SyncStop, options());
  // The controller's SYNC timeout and the valve's own both fire 1.5 periods after the last SYNC.
  expectSafeAndBack(r, Fault::SyncLost, 0x8100, 1.5, 1.5);
  EXPECT_EQ(r.emcy, std::vector<std::uint16_t>{0x8100});
  EXPECT_GE(r.fc.valve_holds, 1u);  // the valve is sent to Pre-operational (its error value)
  EXPECT_GE(r.counters.sync_timeouts, 1u);
  EXPECT_NEAR(static_cast<double>(r.cycles_without_sync), 100.0, 2.0);
}

TEST(Faults, ValveSilentShortIsAMissingValvePdo) {
  const auto r = rig::runBusFault(BusFault::ValveSilentShort, options());
  expectSafeAndBack(r, Fault::ValvePdoMissing, 0x8250, 5.0, 6.0);
  EXPECT_EQ(r.samples_lost, 0u);
}

TEST(Faults, ValveSilentLongIsRebootedWhenBack) {
  const auto r = rig::runBusFault(BusFault::ValveSilentLong, options());
  expectSafeAndBack(r, Fault::ValvePdoMissing, 0x8250, 5.0, 6.0);
  EXPECT_TRUE(sent(r, 0x8130));
  EXPECT_GE(r.fc.nmt_reboots, 1u);
}

TEST(Faults, HalfLoadOfHigherPriorityFramesIsAbsorbed) {
  const auto r = rig::runBusFault(BusFault::FloodHalf, options());
  expectRideThrough(r);
  EXPECT_TRUE(r.emcy.empty());
  EXPECT_EQ(r.samples_lost, 0u);
  EXPECT_EQ(r.counters.tx_dropped, 0u);
}

TEST(Faults, ABabblingNodeStopsTheBusAndTheValveGoesSafeOnItsOwn) {
  const auto r = rig::runBusFault(BusFault::FloodFull, options());
  // Nothing the controller sends gets through; the valve's SYNC timeout (1.5 periods) vents it.
  expectSafeAndBack(r, Fault::CanOverrun, 0x8110, 3.0, 2.0);
  EXPECT_TRUE(sent(r, 0x8250));
  // Frames queued during the flood expired instead of going out late in a burst.
  EXPECT_EQ(r.counters.rpdo_conflicts, 0u);
}

TEST(Faults, OnePdoWithAWrongLengthIsDiscardedWithAWarning) {
  const auto r = rig::runBusFault(BusFault::PdoShortOnce, options());
  expectRideThrough(r);
  EXPECT_EQ(r.emcy, std::vector<std::uint16_t>{0x8210});
  EXPECT_TRUE(r.emcy_reset);
  EXPECT_EQ(r.counters.wrong_length, 1u);
  EXPECT_EQ(r.samples_lost, 1u);
}

TEST(Faults, PdosWithAWrongLengthAreNeverDecoded) {
  const auto r = rig::runBusFault(BusFault::PdoLong, options());
  expectSafeAndBack(r, Fault::PositionMissing, 0x8250, 2.0, 6.0);
  EXPECT_EQ(r.emcy.front(), 0x8210);  // the warning comes first, at the first bad frame
  EXPECT_GE(r.counters.wrong_length, 190u);
}

TEST(Faults, SyncWithAWrongLengthIsIgnoredAndTimesOut) {
  const auto r = rig::runBusFault(BusFault::SyncWrongLength, options());
  expectSafeAndBack(r, Fault::SyncLost, 0x8100, 1.5, 1.5);
  EXPECT_TRUE(sent(r, 0x8240));
}

TEST(Faults, HeartbeatsWithAWrongLengthTimeOut) {
  const auto r = rig::runBusFault(BusFault::HeartbeatWrongLength, options());
  expectSafeAndBack(r, Fault::SensorHeartbeat, 0x8130, 251.0, 252.0);
  EXPECT_GE(r.detect_cycles, 150.0);  // the last good heartbeat plus 250 ms
  EXPECT_GE(r.fc.nmt_reboots, 1u);
}

TEST(Faults, ASecondNodeWithTheControllersIdIsACollision) {
  const auto r = rig::runBusFault(BusFault::DuplicateController, options());
  // Its boot-up comes in on 0x701, which only this node may send: immediate.
  expectSafeAndBack(r, Fault::IdCollision, 0x8150, 0.0, 0.0);
  EXPECT_GE(r.fc.collisions, 10u);
  EXPECT_EQ(r.fc.last_collision_cob, 0x701u);
  EXPECT_GE(r.fc.valve_holds, 1u);
}

TEST(Faults, ASecondSensorIsAConflictAndACollision) {
  const auto r = rig::runBusFault(BusFault::DuplicateSensor, options());
  expectSafeAndBack(r, Fault::SensorState, 0x8130, 1.0, 2.0);  // its boot-up on 0x702
  EXPECT_TRUE(sent(r, 0x8150));
  EXPECT_GE(r.counters.rpdo_conflicts, 990u);
}

TEST(Faults, ErrorPassiveGoesSafe) {
  const auto r = rig::runBusFault(BusFault::ErrorPassive, options());
  expectSafeAndBack(r, Fault::BusError, 0x8120, 1.0, 2.0);
}

TEST(Faults, BusOffReportsRecoveredFromBusOffAfterTheRestart) {
  const auto r = rig::runBusFault(BusFault::BusOff, options());
  expectSafeAndBack(r, Fault::BusOff, 0x8140, 1.0, 2.0);
  EXPECT_EQ(r.emcy, std::vector<std::uint16_t>{0x8140});  // nothing while off the bus
}

TEST(Faults, ControllerOverflowIsAnOverrun) {
  const auto r = rig::runBusFault(BusFault::CanOverflow, options());
  expectSafeAndBack(r, Fault::CanOverrun, 0x8110, 1.0, 2.0);
}

// Injected before the controller starts: the loop never ran, so the reaction is the start-up limit
// (1 s after Operational); the valve was at its safe value all along; moved back, the loop starts.
TEST(Faults, ATpdoMovedBeforeTheStartIsNoPositionAfterOneSecond) {
  const auto r = rig::runBusFault(BusFault::SensorPdoMovedAtStart, options());
  EXPECT_EQ(r.first, Fault::NoPosition) << nodes::toString(r.first);
  EXPECT_NEAR(r.detect_cycles, 1000.0, 5.0);
  EXPECT_TRUE(sent(r, 0x8250));
  EXPECT_TRUE(r.emcy_reset);
  EXPECT_TRUE(r.recovered);
  EXPECT_GE(r.resume_s, 0.0);
  EXPECT_LE(r.resume_s, 0.7);
  EXPECT_LE(r.max_step_v, kStepBound);
}

TEST(Faults, RunsAreRepeatable) {
  const auto a = rig::runBusFault(BusFault::PdoDropRandom, options());
  const auto b = rig::runBusFault(BusFault::PdoDropRandom, options());
  EXPECT_EQ(a.samples_lost, b.samples_lost);
  EXPECT_EQ(a.rmseEnd(), b.rmseEnd());
  EXPECT_EQ(rig::faultTableMarkdown({a}), rig::faultTableMarkdown({b}));
}

// ---- The pieces of the CANopen layer the faults rely on ----

namespace {
using canopen::Frame;
using canopen::VirtualBus;

Frame frame(std::uint32_t id, std::uint8_t len, std::uint8_t fill = 0) {
  Frame f;
  f.id = id;
  f.len = len;
  for (int i = 0; i < len; ++i) f.data[i] = static_cast<std::uint8_t>(fill + i);
  return f;
}

struct Sink : canopen::BusClient {
  std::vector<std::pair<canopen::TimeUs, std::uint32_t>> got;
  void onFrame(const Frame& f, canopen::TimeUs now) override { got.emplace_back(now, f.id); }
  void advance(canopen::TimeUs) override {}
  canopen::TimeUs nextDeadline() const override { return canopen::kNever; }
};
}  // namespace

TEST(BusModel, LowestIdentifierWinsAndFramesTakeTheirBitTime) {
  VirtualBus bus;
  bus.setBitrate(1'000'000, 4);
  auto& a = bus.addPort();
  auto& b = bus.addPort();
  Sink sink;
  bus.addPort(&sink);
  a.send(frame(0x300, 8));
  b.send(frame(0x100, 8));
  b.send(frame(0x080, 0));
  bus.advanceBy(1000);
  ASSERT_EQ(sink.got.size(), 3u);
  // 0x300 and 0x100 are queued together: 0x100 wins; then 0x080 (b's next) beats 0x300.
  EXPECT_EQ(sink.got[0].second, 0x100u);
  EXPECT_EQ(sink.got[1].second, 0x080u);
  EXPECT_EQ(sink.got[2].second, 0x300u);
  const auto t8 = bus.frameTimeUs(frame(0x100, 8));
  EXPECT_EQ(t8, 123);  // 111 bits + stuffing at 1 Mbit/s
  EXPECT_EQ(sink.got[0].first, t8);
  EXPECT_EQ(sink.got[2].first, 2 * t8 + bus.frameTimeUs(frame(0x80, 0)));
  // A full port queue refuses frames; a frame past its deadline is dropped unsent.
  for (int i = 0; i < 4; ++i) EXPECT_TRUE(a.send(frame(0x400, 8)));
  EXPECT_FALSE(a.send(frame(0x400, 8)));
  EXPECT_EQ(a.dropped(), 1u);
  bus.advanceBy(10'000);
  b.sendUntil(frame(0x500, 8), bus.now() + 50);
  b.sendUntil(frame(0x501, 8), bus.now() + 50);  // behind the first: not on the bus by its deadline
  bus.advanceBy(1000);
  EXPECT_EQ(b.expired(), 1u);
  EXPECT_EQ(sink.got.back().second, 0x500u);
}

namespace {
const char* kOd = PAMC_SOURCE_DIR "/od/";
}

TEST(BusModel, SynchronousRpdosOutsideTheWindowDuplicatesAndConflicts) {
  VirtualBus bus;
  auto& port = bus.addPort();
  auto& tool = bus.addPort();
  auto ctrl = canopen::Node::fromEds(std::string(kOd) + "controller.eds", port);
  port.setClient(ctrl.get());
  ctrl->start(0);
  ctrl->applyNmt(canopen::NmtCommand::Start);
  auto& rp = ctrl->rpdo(1);
  auto pos = ctrl->od().ref<std::int32_t>(0x3000, 0);
  bus.advanceTo(1000);  // SYNC 1
  tool.send(frame(0x182, 4, 1));
  tool.send(frame(0x182, 4, 1));  // the same again: ignored
  bus.advanceTo(2000);            // SYNC 2 latches it
  EXPECT_EQ(rp.syncsSinceReception(), 0u);
  EXPECT_EQ(rp.duplicates(), 1u);
  EXPECT_EQ(pos.get(), 0x04030201);
  tool.send(frame(0x182, 4, 1));
  tool.send(frame(0x182, 4, 9));  // other data in the same cycle: the cycle is discarded
  bus.advanceTo(3000);
  EXPECT_EQ(rp.conflicts(), 1u);
  EXPECT_TRUE(rp.conflictInLastCycle());
  EXPECT_EQ(rp.syncsSinceReception(), 1u);
  bus.advanceTo(3900);  // 900 us after the SYNC: after the 800 us window
  tool.send(frame(0x182, 4, 5));
  bus.advanceTo(4000);
  EXPECT_EQ(rp.late(), 1u);
  EXPECT_EQ(rp.syncsSinceReception(), 2u);
  EXPECT_EQ(pos.get(), 0x04030201);  // never decoded
}

TEST(BusModel, AFrameOnTheNodesOwnIdentifierIsACollision) {
  VirtualBus bus;
  auto& port = bus.addPort();
  auto& tool = bus.addPort();
  auto ctrl = canopen::Node::fromEds(std::string(kOd) + "controller.eds", port);
  port.setClient(ctrl.get());
  std::vector<std::uint32_t> seen;
  ctrl->onCollision([&](const Frame& f, canopen::TimeUs) { seen.push_back(f.id); });
  ctrl->start(0);
  ctrl->applyNmt(canopen::NmtCommand::Start);
  tool.send(frame(0x701, 1));  // boot-up of another node 1
  tool.send(frame(0x081, 8));  // its EMCY
  tool.send(frame(0x203, 2));  // the valve setpoint TPDO
  tool.send(frame(0x080, 0));  // a SYNC while this node produces SYNC
  tool.send(frame(0x702, 1));  // the sensor's heartbeat: fine
  bus.flush();
  EXPECT_EQ(seen, (std::vector<std::uint32_t>{0x701, 0x081, 0x203, 0x080}));
  EXPECT_EQ(ctrl->counters().cob_id_collisions, 4u);
}

TEST(BusModel, SyncConsumerTimesOutAfterOneAndAHalfPeriods) {
  VirtualBus bus;
  auto& port = bus.addPort();
  auto& tool = bus.addPort();
  auto sensor = canopen::Node::fromEds(std::string(kOd) + "sensor.eds", port);
  port.setClient(sensor.get());
  sensor->od().entry(0x1006, 0).set<std::uint32_t>(1000);
  std::vector<canopen::TimeUs> timeouts;
  sensor->onSyncTimeout([&](canopen::TimeUs now) { timeouts.push_back(now); });
  sensor->start(0);
  bus.advanceTo(10'000);
  EXPECT_TRUE(timeouts.empty());  // monitoring starts with the first SYNC
  tool.send(frame(0x080, 0));
  bus.advanceTo(11'000);
  tool.send(frame(0x080, 0));
  bus.advanceTo(20'000);
  EXPECT_EQ(timeouts, std::vector<canopen::TimeUs>{12'500});
  EXPECT_TRUE(sensor->sync().timedOut());
  tool.send(frame(0x080, 0));
  bus.flush();
  EXPECT_FALSE(sensor->sync().timedOut());
}

// The valve that loses its SYNC (the producer stops while everything stays Operational) goes to its
// error value and says so: EMCY 0x8100 on node 3 and the communication bit of its 0x1001. An SDO write
// to 0x6411:01 is stored but does not re-arm the output; the next synchronous command does, with an
// EMCY error reset.
TEST(FaultRig, AValveWithoutSyncShowsItsErrorStateUntilAFreshCommand) {
  rig::FaultRigOptions o;
  o.od_dir = std::string(PAMC_SOURCE_DIR) + "/od";
  rig::detail::Rig r(rig::BusFault::SyncStop, o);
  std::vector<std::uint16_t> valve_emcy;
  r.bus.addTap([&](const canopen::Frame& f, canopen::TimeUs) {
    if (f.id == 0x83 && f.len == 8) valve_emcy.push_back(canopen::getU16(f.data));
  });
  while (r.ctrl->runTime() < 1.0) r.step(1000);
  EXPECT_FALSE(r.emu->valveInError());
  EXPECT_EQ(r.emu->valve().emcy().errorRegister(), 0);
  rig::detail::begin(r, rig::BusFault::SyncStop);
  for (int k = 0; k < 20; ++k) r.step(1000);
  EXPECT_TRUE(r.emu->valveInError());
  ASSERT_EQ(valve_emcy.size(), 1u);
  EXPECT_EQ(valve_emcy[0], canopen::kEmcyCommunication);
  EXPECT_NE(r.emu->valve().emcy().errorRegister() & 0x10, 0) << "communication bit of 0x1001";
  auto& out = r.emu->valve().od().entry(0x6411, 1);
  const std::int16_t v = 20000;
  std::uint8_t b[2];
  std::memcpy(b, &v, 2);
  EXPECT_EQ(r.emu->valve().od().remoteWrite(out, b, 2), 0u);
  for (int k = 0; k < 5; ++k) r.step(1000);
  EXPECT_TRUE(r.emu->valveInError()) << "an SDO write of the output does not re-arm it";
  rig::detail::end(r, rig::BusFault::SyncStop);
  for (int k = 0; k < 2000 && r.emu->valveInError(); ++k) r.step(1000);
  EXPECT_FALSE(r.emu->valveInError());
  ASSERT_EQ(valve_emcy.size(), 2u);
  EXPECT_EQ(valve_emcy[1], canopen::kEmcyNoError);
  EXPECT_EQ(r.emu->valve().emcy().errorRegister(), 0);
}
