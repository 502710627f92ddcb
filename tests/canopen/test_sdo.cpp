#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

// Node 5 with a writable string, a write-only and an octet string entry.
std::string sdoTestEds() {
  return makeEds(var(0x2100, "Name", "0x0009", "rw", "init") + var(0x2101, "Secret", "0x0007", "wo", "7") +
                 var(0x2102, "Blob", "0x000A", "rw", "0102") + var(0x2103, "Gain", "0x0011", "rw", "1.0"));
}

struct Result {
  bool done = false;
  std::uint32_t code = 0xFFFFFFFF;
  std::vector<std::uint8_t> data;
  TimeUs t = -1;
};

SdoClient::Callback capture(Result& r, VirtualBus& bus) {
  return [&r, &bus](std::uint32_t code, const std::uint8_t* d, std::size_t len) {
    r.done = true;
    r.code = code;
    r.data.assign(d, d + len);
    r.t = bus.now();
  };
}

TEST(SdoServer, ExpeditedDownloadOf0x1017) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  // 2B = expedited, 2 bytes; index 1017 little-endian; sub 00; data E8 03 (1000) in bytes 4-5.
  EXPECT_EQ(net.exchange("601#2B171000E8030000"), Frames{"581#6017100000000000"});
  EXPECT_EQ(ctrl.od().entry(0x1017, 0).get<std::uint16_t>(), 1000);
  EXPECT_EQ(ctrl.heartbeatProducer().periodUs(), 1'000'000);
}

TEST(SdoServer, ExpeditedUploadOfOneTwoAndFourBytes) {
  Network net;
  net.addEds(odPath("controller.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("601#4017100000000000"), Frames{"581#4B17100064000000"});
  EXPECT_EQ(net.exchange("601#4006100000000000"), Frames{"581#43061000E8030000"});
  EXPECT_EQ(net.exchange("601#4010200000000000"), Frames{"581#4F10200001000000"});
}

TEST(SdoServer, SegmentedUploadWithToggleBit) {
  Network net;
  net.addEds(odPath("controller.eds"));
  net.startAll();
  EXPECT_EQ(net.exchange("601#4008100000000000"), Frames{"581#410810000F000000"});  // 15 bytes
  EXPECT_EQ(net.exchange("601#6000000000000000"), Frames{"581#0070616D6320636F"});  // "pamc co"
  EXPECT_EQ(net.exchange("601#7000000000000000"), Frames{"581#106E74726F6C6C65"});  // "ntrolle"
  EXPECT_EQ(net.exchange("601#6000000000000000"), Frames{"581#0D72000000000000"});  // "r", n=6, last
}

TEST(SdoServer, SegmentedDownloadWithToggleBit) {
  Network net;
  Node& node = net.addText(sdoTestEds(), 5);
  net.startAll();
  EXPECT_EQ(net.exchange("605#210021000A000000"), Frames{"585#6000210000000000"});
  EXPECT_EQ(net.exchange("605#0030313233343536"), Frames{"585#2000000000000000"});
  EXPECT_EQ(net.exchange("605#1937383900000000"), Frames{"585#3000000000000000"});
  EXPECT_EQ(node.od().entry(0x2100, 0).str(), "0123456789");
  // Expedited write of a shorter string shortens it.
  EXPECT_EQ(net.exchange("605#2700210041424300"), Frames{"585#6000210000000000"});
  EXPECT_EQ(node.od().entry(0x2100, 0).str(), "ABC");
}

TEST(SdoServer, AbortCodes) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.addText(sdoTestEds(), 5);
  ctrl.od().validate<double>(0x2000, 1, [](double v) { return v > 5.0 ? kAbortValueRange : kSdoOk; });
  net.startAll();
  // Object does not exist / sub-index does not exist.
  EXPECT_EQ(net.exchange("601#4000500000000000"), Frames{"581#8000500000000206"});
  EXPECT_EQ(net.exchange("601#4018100900000000"), Frames{"581#8018100911000906"});
  // Read-only and write-only.
  EXPECT_EQ(net.exchange("601#2300100001000000"), Frames{"581#8000100002000106"});
  EXPECT_EQ(net.exchange("605#4001210000000000"), Frames{"585#8001210001000106"});
  EXPECT_EQ(net.exchange("605#2301210009000000"), Frames{"585#6001210000000000"});  // but writable
  // Length: 1 byte and 4 bytes into UNSIGNED16.
  EXPECT_EQ(net.exchange("601#2F17100005000000"), Frames{"581#8017100013000706"});
  EXPECT_EQ(net.exchange("601#2317100001000000"), Frames{"581#8017100012000706"});
  // Length: segmented transfer announcing 5 bytes but delivering 7.
  EXPECT_EQ(net.exchange("605#2100210005000000"), Frames{"585#6000210000000000"});
  EXPECT_EQ(net.exchange("605#0141424344454647"), Frames{"585#8000210010000706"});
  // Length: announced size of a REAL64 is not 8.
  EXPECT_EQ(net.exchange("601#2100200109000000"), Frames{"581#8000200112000706"});
  // Value range from the EDS limits (0x2010 is 0..5).
  EXPECT_EQ(net.exchange("601#2F10200006000000"), Frames{"581#8010200031000906"});
  EXPECT_EQ(ctrl.od().entry(0x2010, 0).get<std::uint8_t>(), 1);
  // Value range refused by the application (within the EDS limit 10): kp = 8.0 (segmented, 8 bytes).
  EXPECT_EQ(net.exchange("601#2100200108000000"), Frames{"581#6000200100000000"});
  EXPECT_EQ(net.exchange("601#0000000000000020"), Frames{"581#2000000000000000"});
  EXPECT_EQ(net.exchange("601#1D40000000000000"), Frames{"581#8000200130000906"});
  EXPECT_DOUBLE_EQ(ctrl.od().entry(0x2000, 1).get<double>(), 0.1);
  // kp = -1.0 is below LowLimit 0: expedited frames cannot carry 8 bytes, so segmented again.
  EXPECT_EQ(net.exchange("601#2100200108000000"), Frames{"581#6000200100000000"});
  EXPECT_EQ(net.exchange("601#000000000000F0"), Frames{});  // 7-byte frame: wrong length, ignored
  EXPECT_EQ(net.exchange("601#00000000000000F0"), Frames{"581#2000000000000000"});
  EXPECT_EQ(net.exchange("601#1DBF000000000000"), Frames{"581#8000200132000906"});
  // Toggle bit error: the first upload segment must have t = 0.
  EXPECT_EQ(net.exchange("601#4008100000000000"), Frames{"581#410810000F000000"});
  EXPECT_EQ(net.exchange("601#7000000000000000"), Frames{"581#8008100000000305"});
  // Segment without a transfer, block transfer and command specifier 7 are invalid commands.
  EXPECT_EQ(net.exchange("601#6000000000000000"), Frames{"581#8008100001000405"});
  EXPECT_EQ(net.exchange("601#C600100000000000"), Frames{"581#8000100001000405"});
  EXPECT_EQ(net.exchange("601#E000000000000000"), Frames{"581#8000000001000405"});
  EXPECT_GE(ctrl.counters().sdo_aborts_sent, 12u);
  EXPECT_EQ(ctrl.counters().wrong_length, 1u);
}

TEST(SdoServer, TimeoutAbortsAStalledTransfer) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  net.bus.advanceTo(5'000);
  EXPECT_EQ(net.exchange("601#4008100000000000"), Frames{"581#410810000F000000"});
  net.bus.advanceTo(500'000);
  EXPECT_EQ(net.exchange("601#6000000000000000"), Frames{"581#0070616D6320636F"});  // restarts the timer
  net.recorder.log.clear();
  net.bus.advanceTo(2'000'000);
  auto aborts = net.recorder.matching("581#");
  ASSERT_EQ(aborts.size(), 1u);
  EXPECT_EQ(aborts[0].frame, "581#8008100000000405");
  EXPECT_EQ(aborts[0].t, 1'500'000);
  EXPECT_FALSE(ctrl.sdoServer().busy());
}

TEST(SdoClient, TalksToServersOverTheBus) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  Node& sensor = net.addEds(odPath("sensor.eds"));
  Node& other = net.addEds(odPath("controller.eds"), 4);
  Node& five = net.addText(sdoTestEds(), 5);
  other.od().validate<double>(0x2000, 1, [](double v) { return v > 5.0 ? kAbortValueRange : kSdoOk; });
  net.startAll();
  SdoClient& client = ctrl.sdoClient();

  Result r;
  ASSERT_TRUE(client.upload(2, 0x1008, 0, capture(r, net.bus)));
  EXPECT_FALSE(client.upload(2, 0x1008, 0, capture(r, net.bus)));  // busy
  net.bus.flush();
  ASSERT_TRUE(r.done);
  EXPECT_EQ(r.code, kSdoOk);
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), "pamc linear position sensor");

  r = Result{};
  ASSERT_TRUE(client.downloadValue<std::uint16_t>(2, 0x1017, 0, 200, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kSdoOk);
  EXPECT_EQ(sensor.od().entry(0x1017, 0).get<std::uint16_t>(), 200);

  r = Result{};
  ASSERT_TRUE(client.downloadValue<double>(4, 0x2000, 1, 0.25, capture(r, net.bus)));  // segmented
  net.bus.flush();
  EXPECT_EQ(r.code, kSdoOk);
  EXPECT_DOUBLE_EQ(other.od().entry(0x2000, 1).get<double>(), 0.25);

  r = Result{};
  ASSERT_TRUE(client.downloadValue<double>(4, 0x2000, 1, 8.0, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kAbortValueRange);
  EXPECT_DOUBLE_EQ(other.od().entry(0x2000, 1).get<double>(), 0.25);

  r = Result{};
  ASSERT_TRUE(client.downloadValue<std::uint32_t>(2, 0x1000, 0, 1, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kAbortReadOnly);

  r = Result{};
  ASSERT_TRUE(client.upload(2, 0x5000, 0, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kAbortNoObject);

  // Longer than the 32 bytes reserved for the string: refused before any segment.
  const std::string too_long = "a longer name than the entry can hold";
  r = Result{};
  ASSERT_TRUE(client.download(5, 0x2100, 0, reinterpret_cast<const std::uint8_t*>(too_long.data()), too_long.size(),
                              capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kAbortLengthTooHigh);

  const std::string text = "a name sent in four segments";  // 28 bytes: 4 x 7
  r = Result{};
  ASSERT_TRUE(client.download(5, 0x2100, 0, reinterpret_cast<const std::uint8_t*>(text.data()), text.size(),
                              capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(r.code, kSdoOk);
  EXPECT_EQ(five.od().entry(0x2100, 0).str(), text);
  r = Result{};
  ASSERT_TRUE(client.upload(5, 0x2100, 0, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(std::string(r.data.begin(), r.data.end()), text);
}

TEST(SdoClient, TimeoutWhenTheServerIsSilent) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  net.bus.advanceTo(10'000);
  Result r;
  ASSERT_TRUE(ctrl.sdoClient().upload(9, 0x1017, 0, capture(r, net.bus)));
  net.bus.advanceTo(1'009'999);
  EXPECT_FALSE(r.done);
  net.recorder.log.clear();
  net.bus.advanceTo(2'000'000);
  ASSERT_TRUE(r.done);
  EXPECT_EQ(r.code, kAbortTimeout);
  EXPECT_EQ(r.t, 1'010'000);
  auto aborts = net.recorder.matching("609#");
  ASSERT_EQ(aborts.size(), 1u);
  EXPECT_EQ(aborts[0].frame, "609#8017100000000405");
  EXPECT_FALSE(ctrl.sdoClient().busy());
}

TEST(SdoClient, DetectsToggleErrorOfAFaultyServer) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  Result r;
  net.recorder.log.clear();
  ASSERT_TRUE(ctrl.sdoClient().upload(7, 0x2100, 0, capture(r, net.bus)));
  net.bus.flush();
  EXPECT_EQ(net.exchange("587#4100210009000000"), Frames{"607#6000000000000000"});
  EXPECT_EQ(net.exchange("587#1041424344454647"), Frames{"607#8000210000000305"});
  EXPECT_TRUE(r.done);
  EXPECT_EQ(r.code, kAbortToggleBit);
}

TEST(SdoClient, ServerAbortIsReported) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  Result r;
  ASSERT_TRUE(ctrl.sdoClient().downloadValue<std::uint8_t>(7, 0x2000, 0, 1, capture(r, net.bus)));
  net.send("587#8000200002000106");
  EXPECT_TRUE(r.done);
  EXPECT_EQ(r.code, kAbortReadOnly);
  EXPECT_EQ(ctrl.counters().sdo_aborts_received, 1u);
}

}  // namespace
}  // namespace pamc::canopen::test
