#include <algorithm>
#include <fstream>
#include <iterator>

#include "canopen/ini.hpp"
#include "canopen/nmt_master.hpp"

#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

struct Seen {
  std::uint8_t id;
  SlaveEvent ev;
  bool operator==(const Seen& o) const { return id == o.id && ev == o.ev; }
};
std::ostream& operator<<(std::ostream& os, const Seen& s) { return os << int(s.id) << ":" << slaveEventName(s.ev); }

// The controller's dictionary consumes the heartbeats of nodes 2 and 3 (250 ms); the tool port plays
// the slaves.
struct MasterRig {
  MasterRig() : ctrl(net.addEds(odPath("controller.eds"))), master(ctrl) {
    master.addSlave(2);
    master.addSlave(3);
    master.onEvent([this](std::uint8_t id, SlaveEvent ev, TimeUs) { seen.push_back({id, ev}); });
    net.startAll();
    master.begin(net.bus.now());  // starts both (nothing to boot)
    net.bus.flush();
    EXPECT_EQ(nmt(), (Frames{"000#0102", "000#0103"}));
  }
  Frames nmt() {
    Frames v;
    for (const auto& l : net.recorder.matching("000#")) v.push_back(l.frame);
    net.recorder.log.clear();
    return v;
  }
  Network net;
  Node& ctrl;
  NmtMaster master;
  std::vector<Seen> seen;
};

TEST(NmtMaster, StartsASlaveAfterItsBootUp) {
  MasterRig r;
  r.net.send("702#00");
  EXPECT_EQ(r.nmt(), Frames{"000#0102"});
  EXPECT_EQ(r.seen, (std::vector<Seen>{{2, SlaveEvent::BootUp}}));
  EXPECT_TRUE(r.master.starting(2, r.net.bus.now()));
  r.net.send("702#05");
  EXPECT_FALSE(r.master.starting(2, r.net.bus.now())) << "Operational ends the start's grace";
  EXPECT_EQ(r.master.counters().starts, 3u);
}

TEST(NmtMaster, RebootsASlaveThatComesBackAfterAHeartbeatLoss) {
  MasterRig r;
  r.net.send("702#05");
  r.nmt();
  r.net.bus.advanceTo(r.net.bus.now() + 400'000);  // 250 ms without a heartbeat
  EXPECT_TRUE(r.master.timedOut(2));
  EXPECT_EQ(r.seen, (std::vector<Seen>{{2, SlaveEvent::Lost}}));
  r.net.send("702#05");  // back, without a boot-up: its state is unknown
  EXPECT_EQ(r.nmt(), Frames{"000#8202"}) << "reset communication";
  EXPECT_EQ(r.master.counters().reboots, 1u);
  r.net.send("702#00");  // its boot-up starts it
  EXPECT_EQ(r.nmt(), Frames{"000#0102"});
}

TEST(NmtMaster, HoldsASlaveUntilTheLastReasonIsReleased) {
  MasterRig r;
  r.net.send("703#05");
  r.master.hold(3, 1);
  r.master.hold(3, 2);  // already held: nothing more on the bus
  r.net.bus.flush();
  EXPECT_EQ(r.nmt(), Frames{"000#8003"});
  EXPECT_EQ(r.master.holdReasons(3), 3u);
  r.net.send("703#00");  // a held slave that boots is not started
  EXPECT_TRUE(r.nmt().empty());
  r.net.send("703#7F");  // nor is it restarted in Pre-operational
  EXPECT_TRUE(r.nmt().empty());
  EXPECT_EQ(r.seen, (std::vector<Seen>{{3, SlaveEvent::BootUp}})) << "the application still hears of the boot-up";
  const TimeUs now = r.net.bus.now();
  r.master.release(3, 1, now);
  r.net.bus.flush();
  EXPECT_TRUE(r.nmt().empty()) << "one reason left";
  r.master.release(3, 2, now);
  r.net.bus.flush();
  EXPECT_EQ(r.nmt(), Frames{"000#0103"});
  EXPECT_EQ(r.master.counters().holds, 1u);
}

TEST(NmtMaster, ASlaveThatFallsBackToPreOperationalIsStartedAgainAndThenDown) {
  MasterRig r;
  r.net.send("702#05");
  r.net.send("702#7F");  // left Operational on its own
  EXPECT_EQ(r.seen, (std::vector<Seen>{{2, SlaveEvent::LeftOperational}}));
  EXPECT_EQ(r.nmt(), Frames{"000#0102"});
  const TimeUs t0 = r.net.bus.now();
  EXPECT_FALSE(r.master.down(2, t0 + 100'000)) << "within the start's grace";
  EXPECT_TRUE(r.master.down(2, t0 + r.master.startGraceUs(2))) << "did not follow the start";
  r.net.bus.flush();
  EXPECT_EQ(r.nmt(), Frames{"000#0102"}) << "another start";
  r.net.send("702#04");
  EXPECT_EQ(r.seen.back(), (Seen{2, SlaveEvent::Stopped}));
  EXPECT_TRUE(r.master.down(2, r.net.bus.now()));
}

TEST(NmtMaster, StartsNothingBeforeItBeginsOrAfterItEnds) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  NmtMaster master(ctrl);
  master.addSlave(2);
  net.startAll();
  net.recorder.log.clear();
  net.send("702#00");
  EXPECT_TRUE(net.recorder.matching("000#").empty()) << "a boot-up before begin()";
  master.begin(net.bus.now());
  net.bus.flush();
  EXPECT_EQ(net.recorder.matching("000#").size(), 1u);
  master.end();
  net.recorder.log.clear();
  net.send("702#00");
  EXPECT_TRUE(net.recorder.matching("000#").empty()) << "a boot-up after end()";
}

TEST(NmtMaster, IgnoresNodesItDoesNotSuperviseAndRefusesBadIds) {
  MasterRig r;
  r.net.send("704#00");
  EXPECT_TRUE(r.nmt().empty());
  EXPECT_TRUE(r.seen.empty());
  EXPECT_FALSE(r.master.down(4, r.net.bus.now()));
  EXPECT_THROW(r.master.addSlave(0), std::invalid_argument);
  EXPECT_THROW(r.master.addSlave(128), std::invalid_argument);
  EXPECT_THROW(r.master.addSlave(r.ctrl.nodeId()), std::invalid_argument);
}

}  // namespace
}  // namespace pamc::canopen::test

namespace pamc::canopen::test {
namespace {

// The controller as the master of the sensor (od/sensor.eds) as node 2, which it boots by `boot`, with
// the dictionary's 0x1F81 entry for it set from the plan's assignment (the dictionary decides).
struct BootRig {
  explicit BootRig(const SlaveBoot& boot, const std::string& sensor_eds = odPath("sensor.eds"))
      : ctrl(net.addEds(odPath("controller.eds"))), sensor(net.addEds(sensor_eds)), master(ctrl) {
    master.addSlave(2);
    master.setBoot(2, boot);
    ctrl.od().find(0x1F81, 2)->set<std::uint32_t>(boot.assignment);
  }
  // The nodes up, then the master's start; `from_start`: only the frames from the master's start on are kept.
  void start(bool from_start = false) {
    net.startAll();
    if (from_start) net.recorder.log.clear();
    master.begin(net.bus.now());
  }
  Network net;
  Node& ctrl;
  Node& sensor;
  NmtMaster master;
};

// CiA 302-2 0x1F81 bit 4, keep alive: back after a heartbeat loss and Operational, the slave keeps its
// state - no reset; back in Pre-operational it is reset as any other slave.
TEST(NmtMaster, AKeptAliveSlaveThatIsOperationalIsNotReset) {
  MasterRig r;
  r.ctrl.od().find(0x1F81, 2)->set<std::uint32_t>(kAssignSlave | kAssignKeepAlive);
  r.master.begin(r.net.bus.now());
  r.net.send("702#05");
  r.nmt();
  r.net.bus.advanceTo(r.net.bus.now() + 400'000);
  ASSERT_TRUE(r.master.timedOut(2));
  r.net.send("702#05");
  EXPECT_EQ(r.nmt(), Frames{}) << "kept alive: no reset";
  EXPECT_EQ(r.master.counters().reboots, 0u);
  EXPECT_EQ(r.master.counters().kept_alive, 1u);
  r.net.bus.advanceTo(r.net.bus.now() + 400'000);
  ASSERT_TRUE(r.master.timedOut(2));
  r.net.send("702#7F");  // back, but not Operational
  EXPECT_EQ(r.nmt(), Frames{"000#8202"}) << "reset communication";
  EXPECT_EQ(r.master.counters().reboots, 1u);
}

// At the master's (re)start a boot slave is configured again - unless it is kept alive and running (then
// its identity is read - 0x1000 at least - but nothing is written to it).
TEST(NmtMasterBoot, AKeptAliveSlaveThatRunsIsNotBootedAgainAtTheMastersStart) {
  for (bool keep : {false, true}) {
    SlaveBoot b;
    b.assignment = kAssignSlave | kAssignBoot | (keep ? kAssignKeepAlive : 0u);
    b.writes = {dcfValue(0x1017, 0, 50, 2)};
    BootRig r(b);
    auto& net = r.net;
    auto& sensor = r.sensor;
    auto& master = r.master;
    r.start();
    // Kept alive, it is first given a consumer time (250 ms) to show it runs; it is Pre-operational, so it
    // is reset and booted as any other.
    net.bus.advanceTo(600'000);
    ASSERT_EQ(sensor.nmtState(), NmtState::Operational);
    ASSERT_EQ(master.counters().boots, 1u);
    const auto writes = net.recorder.matching("602#2").size();   // SDO downloads
    const auto resets = net.recorder.matching("000#82").size();  // to node 2 or to all (000#8200)
    master.end();
    master.begin(net.bus.now());
    net.bus.advanceTo(1'200'000);
    EXPECT_EQ(net.recorder.matching("000#82").size() == resets, keep) << "keep=" << keep;
    EXPECT_EQ(master.counters().boots, keep ? 1u : 2u) << "keep=" << keep;
    EXPECT_EQ(net.recorder.matching("602#2").size() == writes, keep) << "keep=" << keep;
    EXPECT_EQ(master.counters().kept_alive, keep ? 1u : 0u);
    EXPECT_TRUE(master.configured(2));
  }
}

// The boot of a real slave (od/sensor.eds as node 2): identity, a write, its read-back, the start.
TEST(NmtMasterBoot, ChecksIdentityConfiguresReadsBackThenStarts) {
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot | kAssignMandatory;
  b.device_type = 0x00080196;
  b.writes = {dcfValue(0x1017, 0, 50, 2), dcfValue(0x1800, 2, 1, 1)};
  BootRig r(b);
  auto& net = r.net;
  auto& sensor = r.sensor;
  auto& master = r.master;
  master.addSlave(3);  // no boot plan, absent: started blindly, as before
  std::vector<SlaveEvent> seen;
  master.onEvent([&](std::uint8_t, SlaveEvent e, TimeUs) { seen.push_back(e); });
  r.start();
  net.bus.advanceTo(50'000);
  EXPECT_TRUE(master.configured(2));
  EXPECT_EQ(sensor.od().ref<std::uint16_t>(0x1017, 0).get(), 50);
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
  EXPECT_EQ(master.counters().boots, 1u);
  ASSERT_FALSE(seen.empty());
  EXPECT_EQ(seen.back(), SlaveEvent::Configured);
  // The SDO traffic is the boot's: 0x1000 read, two writes, two read-backs.
  EXPECT_EQ(net.recorder.matching("602#").size(), 5u);
}

TEST(NmtMasterBoot, AMismatchStopsTheSlaveAndNamesIt) {
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot;
  b.product_code = 0x1234;
  BootRig r(b);
  auto& net = r.net;
  auto& sensor = r.sensor;
  auto& master = r.master;
  r.start();
  net.bus.advanceTo(50'000);
  ASSERT_NE(master.bootError(2), nullptr);
  EXPECT_EQ(master.bootError(2)->step, BootStep::Identity);
  EXPECT_EQ(master.bootError(2)->text, "0x1018:02 product code is 0x00000002, expected 0x00001234");
  EXPECT_EQ(sensor.nmtState(), NmtState::Stopped);
  // Its next boot-up boots it again (and fails again: same device).
  net.send("000#8202");
  net.bus.advanceTo(100'000);
  EXPECT_EQ(master.counters().boot_failures, 2u);
}

// The boot as CiA 302-2 has it, on the wire: reset communication (one for all nodes: none is kept alive),
// the boot-up, identity, configuration and its read-back, the first heartbeat after it, then the start -
// in that order.
TEST(NmtMasterBoot, ResetBootUpIdentityConfigurationHeartbeatThenStart) {
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot | kAssignMandatory;
  b.device_type = 0x00080196;
  b.writes = {dcfValue(0x1017, 0, 150, 2)};
  BootRig r(b);
  auto& net = r.net;
  auto& sensor = r.sensor;
  auto& master = r.master;
  r.start(true);
  net.bus.advanceTo(600'000);
  ASSERT_EQ(sensor.nmtState(), NmtState::Operational);
  const auto frames = net.recorder.frames();
  auto first = [&](const std::string& prefix, std::size_t from = 0) {
    for (std::size_t i = from; i < frames.size(); ++i)
      if (frames[i].compare(0, prefix.size(), prefix) == 0) return i;
    return frames.size();
  };
  const auto reset = first("000#8200"), bootup = first("702#00"), identity = first("602#40001000"),
             write = first("602#2B171000"), readback = first("602#40171000"), heartbeat = first("702#7F", readback),
             start = first("000#0102");
  EXPECT_EQ(reset, 0u) << "the master's first frame";
  EXPECT_EQ(first("000#8202"), frames.size()) << "no reset to the node itself";
  EXPECT_LT(reset, bootup);
  EXPECT_LT(bootup, identity);
  EXPECT_LT(identity, write);
  EXPECT_LT(write, readback);
  EXPECT_LT(readback, heartbeat);
  EXPECT_LT(heartbeat, start) << "started after its first heartbeat";
  EXPECT_LT(start, frames.size());
  EXPECT_EQ(master.counters().resets, 1u);
  EXPECT_EQ(master.startGraceUs(2), 450'000) << "three heartbeat periods of the 150 ms it was configured with";
}

// A boot step the slave does not answer is tried again up to its retry factor, then the boot fails
// naming the step: no boot-up after the reset (an absent node), no first heartbeat after the
// configuration (a slave that sends none while 0x1016 supervises it).
TEST(NmtMasterBoot, UnansweredStepsAreTriedAgainThenFailNamingTheStep) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.addEds(odPath("sensor.eds"));
  NmtMaster master(ctrl);
  master.addSlave(2);
  master.addSlave(5);  // nobody there
  SlaveBoot silent;
  silent.assignment = kAssignSlave | kAssignBoot | assignRetries(1);
  silent.writes = {dcfValue(0x1017, 0, 0, 2)};  // no heartbeat, but 0x1016 consumes one (250 ms)
  master.setBoot(2, silent);
  SlaveBoot absent;
  absent.assignment = kAssignSlave | kAssignBoot | assignRetries(2);
  master.setBoot(5, absent);
  net.startAll();
  net.recorder.log.clear();
  master.begin(net.bus.now());
  net.bus.advanceTo(1'000'000);
  ASSERT_NE(master.bootError(2), nullptr);
  EXPECT_EQ(master.bootError(2)->step, BootStep::Heartbeat);
  EXPECT_EQ(master.bootError(2)->text, "no heartbeat within 250 ms (its consumer time, 0x1016) of its configuration");
  EXPECT_EQ(master.bootError(5), nullptr) << "still resetting";
  net.bus.advanceTo(3'500'000);
  ASSERT_NE(master.bootError(5), nullptr);
  EXPECT_EQ(master.bootError(5)->step, BootStep::Reset);
  EXPECT_EQ(master.bootError(5)->text, "no boot-up within 1000 ms of NMT reset communication");
  EXPECT_EQ(net.recorder.matching("000#8200").size(), 1u) << "the reset of all at the master's start";
  EXPECT_EQ(net.recorder.matching("000#8205").size(), 2u) << "its two retries, to the node itself";
  EXPECT_EQ(master.counters().boot_retries, 3u) << "a heartbeat and two resets";
  EXPECT_EQ(master.counters().boot_failures, 2u);
  EXPECT_STREQ(bootStepName(BootStep::Heartbeat), "first heartbeat");
}

// 0x1F89: every mandatory slave booted within the boot time, or its boot fails naming it.
TEST(NmtMasterBoot, AMandatorySlaveNotBootedWithinTheBootTimeFails) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  NmtMaster master(ctrl);
  master.addSlave(5);
  SlaveBoot absent;
  absent.assignment = kAssignSlave | kAssignBoot | kAssignMandatory | assignRetries(3);
  master.setBoot(5, absent);
  ctrl.od().find(kObjBootTime, 0)->set<std::uint32_t>(500);
  net.startAll();
  master.begin(net.bus.now());
  net.bus.advanceTo(499'000);
  EXPECT_EQ(master.bootError(5), nullptr);
  net.bus.advanceTo(501'000);
  ASSERT_NE(master.bootError(5), nullptr);
  EXPECT_EQ(master.bootError(5)->step, BootStep::BootTime);
  EXPECT_EQ(master.bootError(5)->text, "not booted within the boot time 0x1F89 of 500 ms");
}

// CiA 302-2: the boot's first SDO request uploads the device type 0x1000:00 - also when 0x1F84 expects
// none (0): it proves the slave is there. A slave that boots up but answers no SDO fails there.
TEST(NmtMasterBoot, TheFirstRequestUploadsTheDeviceTypeAlsoWhenNoneIsExpected) {
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot;
  b.writes = {dcfValue(0x1017, 0, 50, 2)};
  BootRig r(b);
  ASSERT_EQ(r.ctrl.od().find(kObjDeviceType, 2)->asUnsigned(), 0u) << "no device type expected";
  r.start(true);
  r.net.bus.advanceTo(50'000);
  const auto sdo = r.net.recorder.matching("602#");
  ASSERT_FALSE(sdo.empty());
  EXPECT_EQ(sdo.front().frame, "602#4000100000000000");
  EXPECT_TRUE(r.master.configured(2));

  Network net;  // the tool port plays node 5: it boots up, then answers nothing
  NmtMaster master(net.addEds(odPath("controller.eds")));
  master.addSlave(5);
  SlaveBoot mute;
  mute.assignment = kAssignSlave | kAssignBoot | assignRetries(1);
  master.setBoot(5, mute);
  net.startAll();
  master.begin(net.bus.now());
  net.recorder.log.clear();
  net.send("705#00");
  net.bus.advanceTo(net.bus.now() + 3'000'000);
  const auto uploads = net.recorder.matching("605#40");
  ASSERT_EQ(uploads.size(), 2u) << "the upload and its retry";
  EXPECT_EQ(uploads.front().frame, "605#4000100000000000");
  EXPECT_EQ(net.recorder.matching("605#").front().frame, "605#4000100000000000") << "the first SDO request";
  ASSERT_NE(master.bootError(5), nullptr);
  EXPECT_EQ(master.bootError(5)->step, BootStep::Identity);
  EXPECT_EQ(master.bootError(5)->abort_code, kAbortTimeout);
  EXPECT_EQ(master.bootError(5)->text.rfind("0x1000:00 read failed: ", 0), 0u) << master.bootError(5)->text;
}

// CiA 302-2 (as Lely's master): every booted slave gets its own NMT start, also one whose heartbeat
// already says Operational (kept alive) - unless 0x1F80 bit 3 says the master shall not start the slaves.
TEST(NmtMasterBoot, ABootedSlaveThatAlreadyRunsIsStartedUnless0x1F80Bit3) {
  for (bool no_start : {false, true}) {
    SlaveBoot b;
    b.assignment = kAssignSlave | kAssignBoot | kAssignKeepAlive;
    BootRig r(b);
    r.ctrl.od().find(kObjStartup, 0)->set<std::uint32_t>(kStartupMaster | (no_start ? kStartupNoSlaveStart : 0u));
    r.net.startAll();
    r.net.send("000#0102");  // another master started it
    r.net.bus.advanceTo(300'000);
    ASSERT_EQ(r.ctrl.heartbeatConsumer().remoteState(2), NmtState::Operational);
    r.net.recorder.log.clear();
    r.master.begin(r.net.bus.now());
    r.net.bus.advanceTo(400'000);
    EXPECT_EQ(r.master.counters().kept_alive, 1u);
    Frames nmt;
    for (const auto& l : r.net.recorder.matching("000#")) nmt.push_back(l.frame);
    EXPECT_EQ(nmt, no_start ? Frames{} : Frames{"000#0102"}) << "no_start=" << no_start;
  }
}

// A device without RTR has bit 30 of its TPDO COB-IDs set and refuses it cleared: the master reads the
// COB-ID before its first write and keeps the bit in the disable and the enable (bit 31 as written).
TEST(NmtMasterBoot, TpdoCobIdsKeepTheDevicesBit30) {
  std::ifstream in(odPath("sensor.eds"));
  std::string eds((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::string from = "[1800sub1]";
  const auto def = eds.find("DefaultValue=$NODEID+0x180", eds.find(from));
  ASSERT_NE(def, std::string::npos);
  eds.replace(def, 26, "DefaultValue=$NODEID+0x40000180");
  const std::string path = ::testing::TempDir() + "sensor_no_rtr.eds";
  std::ofstream(path) << eds;
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot;
  b.writes = {dcfValue(0x1800, 1, 0x80000182u, 4), dcfValue(0x1800, 2, 1, 1), dcfValue(0x1800, 1, 0x182u, 4)};
  BootRig r(b, path);
  r.sensor.od().addValidator(0x1800, 1, [](const Entry&, const std::uint8_t* d, std::size_t len) {
    return len == 4 && (d[3] & 0x40) != 0 ? kSdoOk : kAbortValueRange;  // no RTR: bit 30 stays set
  });
  ASSERT_EQ(r.sensor.od().find(0x1800, 1)->get<std::uint32_t>(), 0x40000182u);
  r.start(true);
  r.net.bus.advanceTo(400'000);  // through its first heartbeat (100 ms)
  ASSERT_EQ(r.master.bootError(2), nullptr) << r.master.bootError(2)->text;
  EXPECT_TRUE(r.master.configured(2));
  EXPECT_EQ(r.sensor.od().find(0x1800, 1)->get<std::uint32_t>(), 0x40000182u);
  Frames cob;
  for (const auto& l : r.net.recorder.matching("602#")) {
    if (l.frame.compare(4, 8, "40001801") == 0 || l.frame.compare(4, 8, "23001801") == 0) cob.push_back(l.frame);
  }
  EXPECT_EQ(cob,
            (Frames{"602#4000180100000000", "602#23001801820100C0", "602#2300180182010040", "602#4000180100000000"}))
      << "read, disable, enable, read back";
}

// An RPDO COB-ID the master writes keeps the device's bit 30 as well (reserved there: the master does not
// mean to change it); od/valve.eds as node 2 with bit 30 set in its RPDO1 COB-ID.
TEST(NmtMasterBoot, RpdoCobIdsKeepTheDevicesBit30) {
  std::ifstream in(odPath("valve.eds"));
  std::string eds((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const auto def = eds.find("DefaultValue=$NODEID+0x200", eds.find("[1400sub1]"));
  ASSERT_NE(def, std::string::npos);
  eds.replace(def, 26, "DefaultValue=$NODEID+0x40000200");
  const std::string path = ::testing::TempDir() + "valve_bit30.eds";
  std::ofstream(path) << eds;
  Network net;
  NmtMaster master(net.addEds(odPath("controller.eds")));
  Node& valve = net.addEds(path, 2);
  master.addSlave(2);
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot;
  b.writes = {dcfValue(0x1400, 1, 0x80000202u, 4), dcfValue(0x1400, 1, 0x202u, 4)};
  master.setBoot(2, b);
  net.startAll();
  net.recorder.log.clear();
  master.begin(net.bus.now());
  net.bus.advanceTo(400'000);
  ASSERT_EQ(master.bootError(2), nullptr) << master.bootError(2)->text;
  EXPECT_EQ(valve.od().find(0x1400, 1)->get<std::uint32_t>(), 0x40000202u);
  Frames cob;
  for (const auto& l : net.recorder.matching("602#"))
    if (l.frame.compare(6, 6, "001401") == 0) cob.push_back(l.frame);
  EXPECT_EQ(cob,
            (Frames{"602#4000140100000000", "602#23001401020200C0", "602#2300140102020040", "602#4000140100000000"}))
      << "read, disable, enable, read back";
}

// CiA 302-2 as Lely's master has it: a kept-alive slave's identity is read first, then its heartbeat
// decides; not Operational, it is reset communication by itself (no reset of all: a slave is kept alive)
// and after its boot-up goes on at the configuration - its identity is not read again.
TEST(NmtMasterBoot, AKeptAliveSlaveIsIdentifiedBeforeItsStateDecidesAReset) {
  SlaveBoot b;
  b.assignment = kAssignSlave | kAssignBoot | kAssignKeepAlive;
  b.product_code = 2;
  b.writes = {dcfValue(0x1017, 0, 50, 2)};
  BootRig r(b);
  r.net.startAll();
  r.net.bus.advanceTo(300'000);  // its heartbeats say Pre-operational
  r.net.recorder.log.clear();
  r.master.begin(r.net.bus.now());
  r.net.bus.advanceTo(1'200'000);
  ASSERT_TRUE(r.master.configured(2));
  EXPECT_EQ(r.master.counters().boots, 1u);
  Frames seq;
  for (const auto& l : r.net.recorder.log)
    if (l.frame.rfind("000#", 0) == 0 || l.frame.rfind("602#", 0) == 0 || l.frame == "702#00") seq.push_back(l.frame);
  EXPECT_EQ(seq, (Frames{"602#4000100000000000", "602#4018100200000000", "000#8202", "702#00", "602#2B17100032000000",
                         "602#4017100000000000", "000#0102"}));
}

// 0x1F80 bit 1 (CiA 302-2 "start all nodes"): once the mandatory slaves are booted, one NMT start for all
// (000#0100) if every slave may run; an optional slave not booted yet makes it a start each by itself.
TEST(NmtMasterBoot, Bit1StartsAllAtOnceOrEachByItselfOnceTheMandatorySlavesAreBooted) {
  for (bool optional_absent : {false, true}) {
    SlaveBoot b;
    b.assignment = kAssignSlave | kAssignBoot | kAssignMandatory;
    BootRig r(b);
    r.ctrl.od().find(kObjStartup, 0)->set<std::uint32_t>(kStartupMaster | kStartupBroadcastStart);
    if (optional_absent) {
      r.master.addSlave(5);
      SlaveBoot o;
      o.assignment = kAssignSlave | kAssignBoot;
      r.master.setBoot(5, o);
    }
    r.start(true);
    r.net.bus.advanceTo(2'500'000);
    ASSERT_TRUE(r.master.configured(2));
    EXPECT_EQ(r.master.bootError(5) != nullptr, optional_absent);
    Frames starts;
    for (const auto& l : r.net.recorder.matching("000#01")) starts.push_back(l.frame);
    EXPECT_EQ(starts, optional_absent ? Frames{"000#0102"} : Frames{"000#0100"})
        << "optional_absent=" << optional_absent;
  }
}

// The application's configuration (a driver's own writes, Lely's Driver::OnConfig) follows the identity
// and the concise DCF with its read-back, precedes the start, and takes its value as it goes out; a slave
// whose identity is wrong gets none, one that refuses it fails its boot naming the step.
TEST(NmtMasterBoot, TheApplicationsWritesFollowTheConfigurationAndPrecedeTheStart) {
  enum Case { Ok, WrongIdentity, Refused };
  for (Case c : {Ok, WrongIdentity, Refused}) {
    SCOPED_TRACE(c);
    SlaveBoot b;
    b.assignment = kAssignSlave | kAssignBoot;
    if (c == WrongIdentity) b.product_code = 0x1234;
    b.writes = {dcfValue(0x1017, 0, 50, 2)};
    std::uint32_t preset = 0;
    const SlaveBoot::Write write{0x6003, 0, 4, [&preset] { return preset; }};
    if (c == Refused) b.config = {write};  // through setBoot, which keeps it
    BootRig r(b);
    if (c != Refused) r.master.addConfig(2, {write});
    if (c == Refused)
      r.sensor.od().addValidator(0x6003, 0,
                                 [](const Entry&, const std::uint8_t*, std::size_t) { return kAbortValueRange; });
    preset = 0x01020304;  // after addConfig: taken as the write goes out
    r.start(true);
    r.net.bus.advanceTo(400'000);
    Frames seq;
    for (const auto& l : r.net.recorder.log)
      if (l.frame.rfind("602#", 0) == 0 || l.frame.rfind("000#01", 0) == 0) seq.push_back(l.frame);
    if (c == Ok) {
      EXPECT_EQ(seq, (Frames{"602#4000100000000000", "602#2B17100032000000", "602#4017100000000000",
                             "602#2303600004030201", "000#0102"}));
      EXPECT_EQ(r.sensor.od().find(0x6003, 0)->get<std::int32_t>(), 0x01020304);
      continue;
    }
    ASSERT_NE(r.master.bootError(2), nullptr);
    EXPECT_EQ(std::count(seq.begin(), seq.end(), "602#2303600004030201"), c == Refused ? 1 : 0);
    EXPECT_EQ(std::count(seq.begin(), seq.end(), "000#0102"), 0);
    if (c == Refused) {
      EXPECT_EQ(r.master.bootError(2)->step, BootStep::Application);
      EXPECT_EQ(r.master.bootError(2)->abort_code, kAbortValueRange);
      EXPECT_EQ(r.master.bootError(2)->text.rfind("0x6003:00 write refused: ", 0), 0u) << r.master.bootError(2)->text;
      EXPECT_STREQ(bootStepName(BootStep::Application), "application configuration");
    }
  }
}

TEST(NmtMaster, TheStartGraceFollowsTheHeartbeat) {
  MasterRig r;
  EXPECT_EQ(r.master.startGraceUs(2), 750'000) << "no heartbeat configured: three consumer times (250 ms)";
  r.ctrl.od().find(0x1016, 1)->set<std::uint32_t>(0x00020000u);  // not supervised
  r.ctrl.heartbeatConsumer().configure();
  r.master.begin(r.net.bus.now());
  EXPECT_EQ(r.master.startGraceUs(2), NmtMaster::kStartGraceFloorUs);
}

TEST(ConciseDcf, RoundTripAndMalformedStrings) {
  const ConciseDcf d = {dcfValue(0x1800, 1, 0x80000182u, 4), DcfEntry{0x2000, 3, {1, 2, 3}}};
  const auto bytes = encodeConciseDcf(d);
  EXPECT_EQ(bytes.size(), 4u + 7 + 4 + 7 + 3);
  ConciseDcf back;
  std::string why;
  ASSERT_TRUE(decodeConciseDcf(bytes.data(), bytes.size(), back, &why));
  EXPECT_EQ(back, d);
  auto extra = bytes;
  extra.push_back(0);
  EXPECT_FALSE(decodeConciseDcf(extra.data(), extra.size(), back, &why));
  EXPECT_EQ(why, "1 bytes after the last entry");
  EXPECT_FALSE(decodeConciseDcf(bytes.data(), 2, back, &why));
}

TEST(Ini, SectionsKeysAndLines) {
  const auto f = parseIni("; c\n[Bus]\ninterface = can0 ; inline\n\n[sensor]\nnode_id=2\n", "r.ini");
  ASSERT_EQ(f.sections.size(), 2u);
  EXPECT_EQ(f.sections[0].line, 2);
  ASSERT_NE(f.find("bus"), nullptr);
  const IniKey* k = f.find("bus")->find("INTERFACE");
  ASSERT_NE(k, nullptr);
  EXPECT_EQ(k->value, "can0");
  EXPECT_EQ(k->line, 3);
  EXPECT_EQ(f.find("sensor")->find("node_id")->line, 6);
  auto error = [](const std::string& text) {
    try {
      parseIni(text, "r.ini");
    } catch (const IniError& e) {
      return std::string(e.what());
    }
    return std::string("accepted");
  };
  EXPECT_EQ(error("[a]\nx=1\n[b]\n[a]\n"), "r.ini:4: duplicate section [a] (first at line 1)");
  EXPECT_EQ(error("[a]\nx=1\nx=2\n"), "r.ini:3: duplicate key 'x' in [a] (first at line 2)");
  EXPECT_EQ(error("x=1\n"), "r.ini:1: key 'x' outside of any section");
  EXPECT_EQ(error("[a]\njunk\n"), "r.ini:2: syntax error: expected [section], key = value or a ; comment");
  std::uint64_t u = 0;
  double d = 0;
  EXPECT_TRUE(parseIniUnsigned("0x1F", u) && u == 31);
  EXPECT_FALSE(parseIniUnsigned("-1", u));
  EXPECT_FALSE(parseIniUnsigned("12ab", u));
  EXPECT_TRUE(parseIniDouble("2.5e-3", d) && d == 2.5e-3);
  EXPECT_FALSE(parseIniDouble("nan", d));
}

}  // namespace
}  // namespace pamc::canopen::test
