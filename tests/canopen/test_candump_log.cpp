#include <cstdio>
#include <fstream>
#include <sstream>

#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

TEST(CandumpLog, FormatsStandardFrameWithSixDecimalsAndUppercaseHex) {
  Frame f = makeFrame(0x181, 8, nullptr);
  const std::uint8_t bytes[8] = {0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0xAB, 0xcd};
  std::memcpy(f.data, bytes, 8);
  EXPECT_EQ(formatCandumpLine(f, 1700000000123456, "vcan0"), "(1700000000.123456) vcan0 181#010203040506ABCD");
  EXPECT_EQ(formatCandumpLine(makeFrame(0x00A, 0), 1700000000000001, "can1"), "(1700000000.000001) can1 00A#");
}

TEST(CandumpLog, FormatsRemoteExtendedAndErrorFrames) {
  Frame r = makeFrame(0x123, 0);
  r.flags = kFrameRemote;
  EXPECT_EQ(formatFrame(r), "123#R");
  r.len = 4;
  EXPECT_EQ(formatFrame(r), "123#R4");
  Frame x = frame("1ABCDEF0#DEAD");
  EXPECT_TRUE(x.extended());
  EXPECT_EQ(x.id, 0x1ABCDEF0u);
  EXPECT_EQ(formatFrame(x), "1ABCDEF0#DEAD");
  Frame e;
  e.id = 0x004;
  e.len = 8;
  e.flags = kFrameError;
  EXPECT_EQ(formatFrame(e), "20000004#0000000000000000");
}

TEST(CandumpLog, ParsesLinesIncludingRemoteExtendedAndLowercase) {
  CandumpRecord r;
  ASSERT_TRUE(parseCandumpLine("(1700000000.123456) vcan0 181#0102030405060708", r));
  EXPECT_EQ(r.unix_time_us, 1700000000123456);
  EXPECT_EQ(r.interface, "vcan0");
  EXPECT_EQ(r.frame.id, 0x181u);
  EXPECT_EQ(r.frame.len, 8);
  EXPECT_EQ(r.frame.data[7], 0x08);

  ASSERT_TRUE(parseCandumpLine("(1.5) can0 7ff#ab", r));
  EXPECT_EQ(r.unix_time_us, 1500000);
  EXPECT_EQ(r.frame.id, 0x7FFu);
  EXPECT_EQ(r.frame.data[0], 0xAB);

  ASSERT_TRUE(parseCandumpLine("(0.000001) can0 123#R", r));
  EXPECT_TRUE(r.frame.remote());
  EXPECT_EQ(r.frame.len, 0);
  ASSERT_TRUE(parseCandumpLine("(0.000001) can0 123#R8", r));
  EXPECT_EQ(r.frame.len, 8);
  ASSERT_TRUE(parseCandumpLine("(0.000001) can0 12345678#11.22 T", r));  // trailing direction flag ignored
  EXPECT_TRUE(r.frame.extended());
  EXPECT_EQ(r.frame.id, 0x12345678u);
  EXPECT_EQ(r.frame.len, 2);
  ASSERT_TRUE(parseCandumpLine("(0.000001) can0 20000004#0000000000000000", r));
  EXPECT_TRUE(r.frame.error());
  EXPECT_EQ(r.frame.id, 0x004u);
}

TEST(CandumpLog, RejectsMalformedLines) {
  CandumpRecord r;
  std::string err;
  EXPECT_FALSE(parseCandumpLine("181#00", r, &err));
  EXPECT_NE(err.find("timestamp"), std::string::npos);
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 1234#00", r, &err));
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 800#00", r, &err));
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 181#012", r, &err));
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 181#010203040506070809", r, &err));
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 181##1AA", r, &err));
  EXPECT_NE(err.find("FD"), std::string::npos);
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0", r, &err));
  EXPECT_FALSE(parseCandumpLine("(1.000000) can0 181#0G", r, &err));

  std::istringstream in("(1.000000) can0 181#00\n\n(2.000000) can0 xyz\n");
  try {
    readCandumpLog(in, "bad.log");
    FAIL() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("bad.log:3:"), std::string::npos) << e.what();
  }
}

TEST(CandumpLog, RoundTripOfBusTrafficThroughAFile) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.addEds(odPath("sensor.eds"));
  net.addEds(odPath("valve.eds"));
  const std::string path = ::testing::TempDir() + "pamc_candump_roundtrip.log";
  const TimeUs epoch_us = 1700000000000000;
  std::vector<std::pair<TimeUs, Frame>> sent;
  {
    CandumpWriter writer(path, "vcan0");
    net.bus.addTap(writer.tap(epoch_us));
    net.bus.addTap([&](const Frame& f, TimeUs now) { sent.emplace_back(epoch_us + now, f); });
    net.startAll();
    ctrl.sendNmt(NmtCommand::Start, 0);
    ctrl.applyNmt(NmtCommand::Start);
    Frame remote = makeFrame(0x123, 0);
    remote.flags = kFrameRemote;
    net.tool.send(remote);
    net.tool.send(frame("1FFFFFFF#CAFE"));
    net.bus.advanceBy(20'500);
  }
  ASSERT_GT(sent.size(), 40u);
  auto records = readCandumpLog(path);
  ASSERT_EQ(records.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    EXPECT_EQ(records[i].unix_time_us, sent[i].first) << i;
    EXPECT_EQ(records[i].interface, "vcan0");
    EXPECT_EQ(records[i].frame, sent[i].second) << i << " " << formatFrame(sent[i].second);
  }
  std::ifstream in(path);
  std::string first;
  std::getline(in, first);
  EXPECT_EQ(first, "(1700000000.000000) vcan0 701#00");
  std::remove(path.c_str());
}

}  // namespace
}  // namespace pamc::canopen::test
