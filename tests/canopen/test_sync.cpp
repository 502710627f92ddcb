#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

// Collects what a node sends, for driving it directly without a bus.
class CaptureTransport : public Transport {
 public:
  bool send(const Frame& f) override {
    frames.push_back(f);
    return true;
  }
  std::vector<Frame> frames;
};

TEST(Sync, ProducerRunsOnTheConfiguredPeriod) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  EXPECT_TRUE(ctrl.sync().producer());
  net.bus.advanceTo(3'500);
  auto sync = net.recorder.matching("080#");
  ASSERT_EQ(sync.size(), 3u);
  EXPECT_EQ(sync[0].t, 1'000);
  EXPECT_EQ(sync[1].t, 2'000);
  EXPECT_EQ(sync[2].t, 3'000);
  EXPECT_EQ(sync[0].frame, "080#");
}

TEST(Sync, NoDriftOverTenThousandOddPeriodsOnTheVirtualBus) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  net.bus.advanceTo(777);
  EXPECT_EQ(net.exchange("601#23061000EB030000"), Frames{"581#6006100000000000"});  // 1003 us
  std::vector<TimeUs> times;
  net.bus.addTap([&](const Frame& f, TimeUs t) {
    if (f.id == 0x80) times.push_back(t);
  });
  net.bus.advanceTo(777 + 10'000 * 1003);
  ASSERT_EQ(times.size(), 10'000u);
  for (std::size_t k = 0; k < times.size(); ++k) ASSERT_EQ(times[k], 777 + static_cast<TimeUs>(k + 1) * 1003) << k;
  EXPECT_EQ(ctrl.sync().produced(), 10'000u);
  EXPECT_EQ(ctrl.counters().sync_overruns, 0u);
}

TEST(Sync, NoDriftWhenTheDriverWakesLate) {
  // A real event loop wakes up after the deadline; the grid must not move with it.
  CaptureTransport tx;
  Node ctrl(loadDictionary(odPath("controller.eds")), 1, tx);
  ctrl.start(0);
  std::uint8_t d[8] = {0x23, 0x06, 0x10, 0x00, 0xEB, 0x03, 0x00, 0x00};  // 0x1006 = 1003 us
  ctrl.onFrame(makeFrame(0x601, 8, d), 0);
  std::uint32_t seed = 12345;
  int syncs = 0;
  for (TimeUs k = 1; k <= 10'000; ++k) {
    seed = seed * 1664525u + 1013904223u;
    TimeUs jitter_us = static_cast<TimeUs>(seed >> 8) % 900;  // wake 0..899 us late
    tx.frames.clear();
    ctrl.advance(k * 1003 + jitter_us);
    for (const Frame& f : tx.frames) syncs += f.id == 0x80 ? 1 : 0;
    ASSERT_EQ(ctrl.sync().nextDeadline(), (k + 1) * 1003) << k;
  }
  EXPECT_EQ(syncs, 10'000);
  EXPECT_EQ(ctrl.counters().sync_overruns, 0u);
}

TEST(Sync, LateWakeUpSkipsMissedSyncsAndCountsThem) {
  CaptureTransport tx;
  Node ctrl(loadDictionary(odPath("controller.eds")), 1, tx);
  ctrl.start(0);
  tx.frames.clear();
  ctrl.advance(3'500);  // deadlines 1000, 2000, 3000 passed: one SYNC, two missed
  ASSERT_EQ(tx.frames.size(), 1u);
  EXPECT_EQ(tx.frames[0].id, 0x80u);
  EXPECT_EQ(ctrl.counters().sync_overruns, 2u);
  EXPECT_EQ(ctrl.sync().nextDeadline(), 4'000);
}

TEST(Sync, CounterWrapsAtOverflowValue) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  // 0x1019 may only change while no SYNC is produced.
  EXPECT_EQ(net.exchange("601#2F19100004000000"), Frames{"581#8019100022000008"});
  EXPECT_EQ(net.exchange("601#2306100000000000"), Frames{"581#6006100000000000"});
  EXPECT_EQ(net.exchange("601#2F19100001000000"), Frames{"581#8019100030000906"});  // 1 is not allowed
  EXPECT_EQ(net.exchange("601#2F19100004000000"), Frames{"581#6019100000000000"});
  EXPECT_EQ(net.exchange("601#23061000E8030000"), Frames{"581#6006100000000000"});
  std::vector<std::uint8_t> counters;
  ctrl.onSync([&](std::uint8_t c, TimeUs) { counters.push_back(c); });
  net.recorder.log.clear();
  net.bus.advanceBy(5'000);
  EXPECT_EQ(net.recorder.frames(), (Frames{"080#01", "080#02", "080#03", "080#04", "080#01"}));
  EXPECT_EQ(counters, (std::vector<std::uint8_t>{1, 2, 3, 4, 1}));
}

TEST(Sync, ConsumerChecksLengthAndPassesCounter) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  int calls = 0;
  sensor.onSync([&](std::uint8_t counter, TimeUs) {
    ++calls;
    EXPECT_EQ(counter, 0);
  });
  net.startAll();
  net.send("000#0102");
  EXPECT_EQ(net.exchange("080#01"), Frames{});  // 0x1019 = 0: a SYNC has no data
  EXPECT_EQ(sensor.counters().wrong_length, 1u);
  EXPECT_EQ(calls, 0);
  EXPECT_EQ(net.exchange("080#"), Frames{"182#00000000"});
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(sensor.sync().consumed(), 1u);
}

TEST(Sync, CycleOrderLatchThenApplicationThenTpdo) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  Ref<std::int32_t> position = ctrl.od().ref<std::int32_t>(0x3000, 0);
  Ref<std::int16_t> command = ctrl.od().ref<std::int16_t>(0x3002, 0);
  std::vector<std::int32_t> seen;
  ctrl.onSync([&](std::uint8_t, TimeUs) {
    seen.push_back(position.get());
    command.set(static_cast<std::int16_t>(position.get() / 10));
  });
  net.startAll();
  ctrl.applyNmt(NmtCommand::Start);
  net.bus.advanceTo(500);
  net.send("182#E8030000");  // position 1000 arrives between SYNCs
  net.recorder.log.clear();
  net.bus.advanceTo(1'000);
  // The callback saw the latched value and its output left right after the SYNC.
  EXPECT_EQ(seen, std::vector<std::int32_t>{1000});
  EXPECT_EQ(net.recorder.frames(), (Frames{"080#", "203#6400"}));
}

}  // namespace
}  // namespace pamc::canopen::test
