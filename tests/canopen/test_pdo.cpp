#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

TEST(Pdo, SensorTpdoOnEverySyncFromEdsMapping) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  Ref<std::int32_t> position = sensor.od().ref<std::int32_t>(0x6004, 0);
  net.startAll();
  position.set(123456);
  EXPECT_EQ(net.exchange("080#"), Frames{});  // Pre-operational: no PDOs
  net.send("000#0102");
  EXPECT_EQ(net.exchange("080#"), Frames{"182#40E20100"});
  position.set(-2);
  EXPECT_EQ(net.exchange("080#"), Frames{"182#FEFFFFFF"});
  EXPECT_EQ(sensor.tpdo(1).sent(), 2u);
}

TEST(Pdo, SynchronousRpdoIsAppliedAtTheNextSync) {
  Network net;
  Node& valve = net.addEds(odPath("valve.eds"));
  Ref<std::int16_t> out = valve.od().ref<std::int16_t>(0x6411, 1);
  net.startAll();
  net.send("203#3412");
  EXPECT_EQ(out.get(), 0);  // Pre-operational: ignored
  net.send("000#0103");
  net.send("203#3412");
  EXPECT_EQ(out.get(), 0);  // latched, not yet applied
  net.send("080#");
  EXPECT_EQ(out.get(), 0x1234);
  EXPECT_EQ(valve.rpdo(1).received(), 1u);
  EXPECT_EQ(valve.rpdo(1).syncsSinceReception(), 0u);
  net.send("080#");
  EXPECT_EQ(valve.rpdo(1).syncsSinceReception(), 1u);
  net.send("080#");
  EXPECT_EQ(valve.rpdo(1).syncsSinceReception(), 2u);
  // Wrong length: counted, value unchanged.
  net.send("203#99");
  net.send("203#010203");
  net.send("080#");
  EXPECT_EQ(out.get(), 0x1234);
  EXPECT_EQ(valve.rpdo(1).wrongLength(), 2u);
  EXPECT_EQ(valve.counters().wrong_length, 2u);
}

TEST(Pdo, EventDrivenRpdoIsAppliedImmediately) {
  Network net;
  Node& valve = net.addEds(odPath("valve.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("603#2F001402FF000000"), Frames{"583#6000140200000000"});  // type 255
  net.send("000#0103");
  net.send("203#FF7F");
  EXPECT_EQ(valve.od().entry(0x6411, 1).get<std::int16_t>(), 32767);
}

TEST(Pdo, TpdoEveryThirdSync) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("602#2F00180203000000"), Frames{"582#6000180200000000"});
  net.send("000#0102");
  sensor.od().entry(0x6004, 0).set<std::int32_t>(1);
  Frames all;
  for (int i = 0; i < 7; ++i) {
    for (const auto& f : net.exchange("080#")) all.push_back(std::to_string(i + 1) + ":" + f);
  }
  EXPECT_EQ(all, (Frames{"3:182#01000000", "6:182#01000000"}));
}

TEST(Pdo, AcyclicSynchronousTpdoSendsOnTheSyncAfterAnEvent) {
  NodeOptions no_cos;
  no_cos.tpdo_change_of_state = false;
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"), 0, no_cos);
  net.startAll();
  EXPECT_EQ(net.exchange("602#2F00180200000000"), Frames{"582#6000180200000000"});  // type 0
  net.send("000#0102");
  EXPECT_EQ(net.exchange("080#"), Frames{});
  sensor.od().entry(0x6004, 0).set<std::int32_t>(9);
  sensor.tpdo(1).request();
  net.bus.advanceBy(1'000);
  EXPECT_TRUE(net.recorder.matching("182#").empty());  // waits for the SYNC
  EXPECT_EQ(net.exchange("080#"), Frames{"182#09000000"});
  EXPECT_EQ(net.exchange("080#"), Frames{});
}

TEST(Pdo, SyncStartValueDelaysTheFirstTransmission) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("602#2F19100005000000"), Frames{"582#6019100000000000"});  // SYNC counter 1..5
  EXPECT_EQ(net.exchange("602#2300180182010080"), Frames{"582#6000180100000000"});  // disable
  EXPECT_EQ(net.exchange("602#2F00180603000000"), Frames{"582#6000180600000000"});  // start value 3
  EXPECT_EQ(net.exchange("602#2F00180202000000"), Frames{"582#6000180200000000"});  // every 2nd SYNC
  EXPECT_EQ(net.exchange("602#2300180182010000"), Frames{"582#6000180100000000"});  // enable
  EXPECT_EQ(net.exchange("602#2F00180604000000"), Frames{"582#8000180622000008"});  // fixed while valid
  net.send("000#0102");
  Frames sent;
  for (int c : {1, 2, 3, 4, 5, 1, 2}) {
    char sync[16];
    std::snprintf(sync, sizeof sync, "080#%02X", c);
    for (const auto& f : net.exchange(sync)) sent.push_back(std::to_string(c) + ":" + f);
  }
  EXPECT_EQ(sent, (Frames{"3:182#00000000", "5:182#00000000", "2:182#00000000"}));
  EXPECT_EQ(sensor.tpdo(1).sent(), 3u);
}

// Reconfigures the sensor's TPDO1 to event-driven with inhibit time and event timer, by SDO as a tool would.
void makeEventDriven(Network& net, const char* inhibit_100us_le16, const char* event_ms_le16) {
  EXPECT_EQ(net.exchange("602#2300180182010080"), Frames{"582#6000180100000000"});  // disable
  EXPECT_EQ(net.exchange("602#2F001802FF000000"), Frames{"582#6000180200000000"});  // type 255
  EXPECT_EQ(net.exchange(std::string("602#2B001803") + inhibit_100us_le16 + "0000"), Frames{"582#6000180300000000"});
  EXPECT_EQ(net.exchange(std::string("602#2B001805") + event_ms_le16 + "0000"), Frames{"582#6000180500000000"});
  EXPECT_EQ(net.exchange("602#2300180182010000"), Frames{"582#6000180100000000"});  // enable
}

TEST(Pdo, EventDrivenTpdoWithInhibitTimeAndEventTimer) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  Ref<std::int32_t> position = sensor.od().ref<std::int32_t>(0x6004, 0);
  net.startAll();
  makeEventDriven(net, "6400", "3200");  // inhibit 100 x 100 us = 10 ms, event timer 50 ms
  net.bus.advanceTo(1'000);
  net.recorder.log.clear();
  net.send("000#0102");  // entering Operational sends once
  net.bus.advanceTo(5'000);
  position.set(7);  // change within the inhibit time: waits until 11 ms
  net.bus.advanceTo(30'000);
  position.set(8);  // inhibit over: sent at once
  net.bus.advanceTo(30'000);
  net.bus.advanceTo(200'000);  // no change: event timer every 50 ms
  auto tpdo = net.recorder.matching("182#");
  std::vector<std::pair<TimeUs, std::string>> got;
  for (const auto& l : tpdo) got.emplace_back(l.t, l.frame);
  const std::vector<std::pair<TimeUs, std::string>> expected = {{1'000, "182#00000000"},   {11'000, "182#07000000"},
                                                                {30'000, "182#08000000"},  {80'000, "182#08000000"},
                                                                {130'000, "182#08000000"}, {180'000, "182#08000000"}};
  EXPECT_EQ(got, expected);
  EXPECT_TRUE(net.recorder.matching("080#").empty());
}

TEST(Pdo, ApplicationRequestTriggersAnEventDrivenTpdo) {
  NodeOptions no_cos;
  no_cos.tpdo_change_of_state = false;
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"), 0, no_cos);
  net.startAll();
  makeEventDriven(net, "0000", "0000");
  net.send("000#0102");
  net.bus.advanceTo(1'000);
  net.recorder.log.clear();
  sensor.od().entry(0x6004, 0).set<std::int32_t>(5);
  net.bus.advanceTo(2'000);
  EXPECT_TRUE(net.recorder.log.empty());  // no change-of-state detection
  sensor.tpdo(1).request();
  net.bus.advanceTo(3'000);
  EXPECT_EQ(net.recorder.frames(), Frames{"182#05000000"});
}

TEST(Pdo, RemappingBySdoFollowsTheCiA301Procedure) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  // While the PDO exists its mapping cannot change (device state).
  EXPECT_EQ(net.exchange("602#2F001A0000000000"), Frames{"582#80001A0022000008"});
  EXPECT_EQ(net.exchange("602#2300180182010080"), Frames{"582#6000180100000000"});  // disable
  // Entries only change while sub-index 0 is 0.
  EXPECT_EQ(net.exchange("602#23001A0220000365"), Frames{"582#80001A0222000008"});
  EXPECT_EQ(net.exchange("602#2F001A0000000000"), Frames{"582#60001A0000000000"});
  // Not mappable (0x6000 has PDOMapping=0), missing object, wrong length in bits.
  EXPECT_EQ(net.exchange("602#23001A0210000060"), Frames{"582#80001A0241000406"});
  EXPECT_EQ(net.exchange("602#23001A0220000050"), Frames{"582#80001A0200000206"});
  EXPECT_EQ(net.exchange("602#23001A0210000460"), Frames{"582#80001A0241000406"});
  EXPECT_EQ(net.exchange("602#23001A0210000365"), Frames{"582#60001A0200000000"});  // 0x6503 alarms
  EXPECT_EQ(net.exchange("602#23001A0120000460"), Frames{"582#60001A0100000000"});  // 0x6004
  // Three entries of 32 + 16 + 32 bits exceed 64 bits.
  EXPECT_EQ(net.exchange("602#23001A0320000460"), Frames{"582#60001A0300000000"});
  EXPECT_EQ(net.exchange("602#2F001A0003000000"), Frames{"582#80001A0042000406"});
  EXPECT_EQ(net.exchange("602#2F001A0002000000"), Frames{"582#60001A0000000000"});
  // The identifier of an existing PDO cannot change; enabling with a new one is allowed.
  EXPECT_EQ(net.exchange("602#2300180182030000"), Frames{"582#6000180100000000"});  // enable as 0x382
  EXPECT_EQ(net.exchange("602#2300180182010000"), Frames{"582#8000180130000906"});
  EXPECT_EQ(sensor.tpdo(1).cobId(), 0x382u);

  net.send("000#0102");
  sensor.od().entry(0x6004, 0).set<std::int32_t>(0x01020304);
  EXPECT_EQ(net.exchange("080#"), Frames{"382#040302010000"});
  EXPECT_EQ(sensor.tpdo(1).map().size(), 6);
}

TEST(Pdo, RpdoDeadlineMonitoringAndDummyMapping) {
  const std::string eds = makeEds(
      "[1400]\nParameterName=RPDO1 comm\nObjectType=0x9\nSubNumber=4\n\n"
      "[1400sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=5\n\n"
      "[1400sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x200\n\n"
      "[1400sub2]\nParameterName=type\nDataType=0x0005\nAccessType=rw\nDefaultValue=254\n\n"
      "[1400sub5]\nParameterName=event timer\nDataType=0x0006\nAccessType=rw\nDefaultValue=20\n\n"
      "[1600]\nParameterName=RPDO1 map\nObjectType=0x9\nSubNumber=3\n\n"
      "[1600sub0]\nParameterName=n\nDataType=0x0005\nAccessType=rw\nDefaultValue=2\n\n"
      "[1600sub1]\nParameterName=m1\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x00060010\n\n"
      "[1600sub2]\nParameterName=m2\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000008\n\n" +
      var(0x2000, "Value", "0x0005", "rww", "0", 1));
  Network net;
  Node& node = net.addText(eds, 5);
  std::vector<std::pair<unsigned, TimeUs>> timeouts;
  node.onRpdoTimeout([&](unsigned n, TimeUs t) { timeouts.emplace_back(n, t); });
  node.applyNmt(NmtCommand::Start);  // ignored before boot-up
  net.startAll();
  node.applyNmt(NmtCommand::Start);
  net.bus.advanceTo(100'000);
  EXPECT_TRUE(timeouts.empty());  // monitoring starts with the first reception
  net.send("205#AAAA42");         // 2 dummy bytes (UNSIGNED16) then the value
  EXPECT_EQ(node.od().entry(0x2000, 0).get<std::uint8_t>(), 0x42);
  net.bus.advanceTo(110'000);
  net.send("205#000043");
  net.bus.advanceTo(500'000);
  ASSERT_EQ(timeouts.size(), 1u);
  EXPECT_EQ(timeouts[0], (std::pair<unsigned, TimeUs>{1, 130'000}));
  EXPECT_TRUE(node.rpdo(1).timedOut());
  net.send("205#000044");
  EXPECT_FALSE(node.rpdo(1).timedOut());
}

TEST(Pdo, InvalidMappingInEdsIsAConfigurationError) {
  const std::string eds = makeEds(
      "[1A00]\nParameterName=TPDO1 map\nObjectType=0x9\nSubNumber=2\n\n"
      "[1A00sub0]\nParameterName=n\nDataType=0x0005\nAccessType=rw\nDefaultValue=1\n\n"
      "[1A00sub1]\nParameterName=m1\nDataType=0x0007\nAccessType=rw\nDefaultValue=0x20000020\n\n"
      "[1800]\nParameterName=TPDO1 comm\nObjectType=0x9\nSubNumber=3\n\n"
      "[1800sub0]\nParameterName=n\nDataType=0x0005\nAccessType=ro\nDefaultValue=2\n\n"
      "[1800sub1]\nParameterName=COB-ID\nDataType=0x0007\nAccessType=rw\nDefaultValue=$NODEID+0x180\n\n"
      "[1800sub2]\nParameterName=type\nDataType=0x0005\nAccessType=rw\nDefaultValue=1\n\n" +
      var(0x2000, "Value", "0x0006", "rw", "0", 1));  // 16-bit object mapped with 32 bits
  VirtualBus bus;
  try {
    Node node(odFromText(eds, 5), 5, bus.addPort());
    FAIL() << "bad mapping accepted";
  } catch (const OdError& e) {
    EXPECT_NE(std::string(e.what()).find("TPDO1 (0x1A00)"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("0x2000:00, 32 bits"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace pamc::canopen::test
