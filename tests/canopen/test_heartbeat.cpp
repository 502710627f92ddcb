#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

TEST(Heartbeat, ProducerSendsStateEveryPeriod) {
  Network net;
  net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.bus.advanceTo(250'000);
  auto hb = net.recorder.matching("702#");
  ASSERT_EQ(hb.size(), 3u);  // boot-up + two heartbeats
  EXPECT_EQ(hb[0].t, 0);
  EXPECT_EQ(hb[0].frame, "702#00");
  EXPECT_EQ(hb[1].t, 100'000);
  EXPECT_EQ(hb[1].frame, "702#7F");
  EXPECT_EQ(hb[2].t, 200'000);
  net.send("000#0102");
  net.recorder.log.clear();
  net.bus.advanceTo(300'000);
  EXPECT_EQ(net.recorder.frames(), Frames{"702#05"});
}

TEST(Heartbeat, ProducerPeriodChangesBySdo) {
  Network net;
  net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.bus.advanceTo(10'000);
  EXPECT_EQ(net.exchange("602#2B17100032000000"), Frames{"582#6017100000000000"});  // 50 ms
  net.recorder.log.clear();
  net.bus.advanceTo(115'000);
  auto hb = net.recorder.matching("702#");
  ASSERT_EQ(hb.size(), 2u);
  EXPECT_EQ(hb[0].t, 60'000);
  EXPECT_EQ(hb[1].t, 110'000);
  EXPECT_EQ(net.exchange("602#2B17100000000000"), Frames{"582#6017100000000000"});  // 0 = off
  net.recorder.log.clear();
  net.bus.advanceTo(1'000'000);
  EXPECT_TRUE(net.recorder.matching("702#").empty());
}

struct Event {
  std::uint8_t node;
  HeartbeatEvent event;
  NmtState state;
  TimeUs t;
  bool operator==(const Event& o) const { return node == o.node && event == o.event && state == o.state && t == o.t; }
};
std::ostream& operator<<(std::ostream& os, const Event& e) {
  return os << "{node " << int(e.node) << ", " << heartbeatEventName(e.event) << ", " << nmtStateName(e.state)
            << ", t=" << e.t << "}";
}

TEST(Heartbeat, ConsumerReportsStartTimeoutBootUpAndStateChange) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));  // monitors nodes 2 and 3 with 250 ms
  std::vector<Event> events;
  ctrl.onHeartbeat([&](std::uint8_t node, HeartbeatEvent ev, NmtState st, TimeUs t) {
    events.push_back({node, ev, st, t});
  });
  net.startAll();
  EXPECT_EQ(ctrl.heartbeatConsumer().monitoredCount(), 2u);
  net.bus.advanceTo(100'000);
  net.send("702#7F");
  net.bus.advanceTo(200'000);
  net.send("702#7F");  // same state: no event
  net.bus.advanceTo(300'000);
  net.send("702#05");
  net.bus.advanceTo(1'000'000);  // silence: timeout 250 ms after the last heartbeat
  EXPECT_TRUE(ctrl.heartbeatConsumer().timedOut(2));
  net.bus.advanceTo(1'100'000);
  net.send("702#00");  // boot-up
  net.bus.advanceTo(1'200'000);
  net.send("702#7F");
  const std::vector<Event> expected = {
      {2, HeartbeatEvent::Started, NmtState::PreOperational, 100'000},
      {2, HeartbeatEvent::StateChanged, NmtState::Operational, 300'000},
      {2, HeartbeatEvent::Timeout, NmtState::Operational, 550'000},
      {2, HeartbeatEvent::BootUp, NmtState::Initialising, 1'100'000},
      {2, HeartbeatEvent::Started, NmtState::PreOperational, 1'200'000},
  };
  EXPECT_EQ(events, expected);
  EXPECT_EQ(ctrl.heartbeatConsumer().remoteState(2), NmtState::PreOperational);
  EXPECT_EQ(ctrl.heartbeatConsumer().remoteState(3), NmtState::Initialising);  // never heard
}

TEST(Heartbeat, ConsumerWithRealNodesAndWrongLength) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.addEds(odPath("sensor.eds"));
  net.addEds(odPath("valve.eds"));
  std::vector<Event> events;
  ctrl.onHeartbeat([&](std::uint8_t node, HeartbeatEvent ev, NmtState st, TimeUs t) {
    events.push_back({node, ev, st, t});
  });
  net.startAll();
  net.bus.advanceTo(1'000'000);
  // Boot-up messages first (the controller started before the others), then the first heartbeats.
  const std::vector<Event> expected = {
      {2, HeartbeatEvent::BootUp, NmtState::Initialising, 0},
      {3, HeartbeatEvent::BootUp, NmtState::Initialising, 0},
      {2, HeartbeatEvent::Started, NmtState::PreOperational, 100'000},
      {3, HeartbeatEvent::Started, NmtState::PreOperational, 100'000},
  };
  EXPECT_EQ(events, expected);
  EXPECT_FALSE(ctrl.heartbeatConsumer().timedOut(2));
  EXPECT_FALSE(ctrl.heartbeatConsumer().timedOut(3));
  std::uint64_t before = ctrl.counters().wrong_length;
  net.send("703#7F7F");
  EXPECT_EQ(ctrl.counters().wrong_length, before + 1);
}

TEST(Heartbeat, ConsumerEntriesForOneNodeTwiceAreRefused) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  net.startAll();
  // 0x1016:02 = node 2, 300 ms while 0x1016:01 already monitors node 2.
  EXPECT_EQ(net.exchange("601#231610022C010200"), Frames{"581#8016100243000406"});
  // Moving node 3's entry to 500 ms is fine and takes effect.
  EXPECT_EQ(net.exchange("601#23161002F4010300"), Frames{"581#6016100200000000"});
  EXPECT_EQ(ctrl.od().entry(0x1016, 2).get<std::uint32_t>(), 0x000301F4u);
}

}  // namespace
}  // namespace pamc::canopen::test
