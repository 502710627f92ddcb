#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

TEST(Emcy, ProducerFramesErrorRegisterAndHistory) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.recorder.log.clear();
  const std::uint8_t mfr[5] = {1, 2, 3, 4, 5};
  EXPECT_TRUE(sensor.emcy().report(kEmcyHeartbeat, mfr));
  EXPECT_FALSE(sensor.emcy().report(kEmcyHeartbeat, mfr));  // already active: no second frame
  EXPECT_TRUE(sensor.emcy().report(0x2310));                // current error
  net.bus.flush();
  EXPECT_EQ(net.recorder.take(), (Frames{"082#3081110102030405", "082#1023130000000000"}));
  EXPECT_EQ(sensor.od().entry(0x1001, 0).get<std::uint8_t>(), 0x13);
  EXPECT_EQ(sensor.od().entry(0x1003, 0).get<std::uint8_t>(), 2);
  EXPECT_EQ(sensor.od().entry(0x1003, 1).get<std::uint32_t>(), 0x00002310u);
  EXPECT_EQ(sensor.od().entry(0x1003, 2).get<std::uint32_t>(), 0x02018130u);

  EXPECT_TRUE(sensor.emcy().clear(kEmcyHeartbeat));
  net.bus.flush();
  EXPECT_EQ(net.recorder.take(), Frames{"082#0000030000000000"});  // error reset, current error remains
  sensor.emcy().clearAll();
  net.bus.flush();
  EXPECT_EQ(net.recorder.take(), Frames{"082#0000000000000000"});
  EXPECT_EQ(sensor.emcy().errorRegister(), 0);
  // Writing 0 to 0x1003:00 clears the history; other values are refused.
  EXPECT_EQ(net.exchange("602#2F03100001000000"), Frames{"582#8003100030000906"});
  EXPECT_EQ(net.exchange("602#2F03100000000000"), Frames{"582#6003100000000000"});
  EXPECT_EQ(sensor.od().entry(0x1003, 0).get<std::uint8_t>(), 0);
}

TEST(Emcy, InhibitTimeSpacesFrames) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("602#2B1510000A000000"), Frames{"582#6015100000000000"});  // 10 x 100 us
  net.bus.advanceTo(10'000);
  net.recorder.log.clear();
  sensor.emcy().report(0x5000);
  sensor.emcy().report(0x6000);
  net.bus.advanceTo(20'000);
  auto emcy = net.recorder.matching("082#");
  ASSERT_EQ(emcy.size(), 2u);
  EXPECT_EQ(emcy[0].t, 10'000);
  EXPECT_EQ(emcy[0].frame, "082#0050010000000000");
  EXPECT_EQ(emcy[1].t, 11'000);
  EXPECT_EQ(emcy[1].frame, "082#0060010000000000");
}

TEST(Emcy, ConsumerReceivesOtherNodesAndChecksLength) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  Node& valve = net.addEds(odPath("valve.eds"));
  std::vector<EmcyMessage> got;
  ctrl.onEmcy([&](const EmcyMessage& m, TimeUs) { got.push_back(m); });
  net.startAll();
  const std::uint8_t mfr[5] = {0xA, 0xB, 0xC, 0xD, 0xE};
  valve.emcy().report(0xFF01, mfr);
  net.bus.flush();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].node_id, 3);
  EXPECT_EQ(got[0].error_code, 0xFF01);
  EXPECT_EQ(got[0].error_register, kErrRegGeneric | kErrRegManufacturer);
  EXPECT_EQ(got[0].manufacturer[4], 0xE);
  net.send("085#0010");
  EXPECT_EQ(got.size(), 1u);
  EXPECT_EQ(ctrl.counters().wrong_length, 1u);
}

TEST(Emcy, NotSentWhenStopped) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.send("000#0202");
  net.recorder.log.clear();
  EXPECT_FALSE(sensor.emcy().report(0x1000));
  net.bus.flush();
  EXPECT_TRUE(net.recorder.log.empty());
  EXPECT_EQ(sensor.emcy().errorRegister(), kErrRegGeneric);  // the error is still recorded
}

}  // namespace
}  // namespace pamc::canopen::test
