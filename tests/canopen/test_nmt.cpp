#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

TEST(Nmt, BootUpFrameThenPreOperational) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  EXPECT_EQ(sensor.nmtState(), NmtState::Initialising);
  net.send("602#4017100000000000");  // not booted: ignored
  EXPECT_EQ(net.recorder.frames(), Frames{"602#4017100000000000"});
  EXPECT_EQ(sensor.counters().ignored_in_state, 1u);
  net.recorder.log.clear();
  net.startAll();
  EXPECT_EQ(net.recorder.frames(), Frames{"702#00"});
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
}

TEST(Nmt, AutoOperationalNodeStartsWithoutMaster) {
  NodeOptions options;
  options.auto_operational = true;
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"), 0, options);
  net.startAll();
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
  EXPECT_EQ(net.exchange("080#"), Frames{"182#00000000"});
}

TEST(Nmt, SlaveStateMachineFollowsMasterCommands) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  std::vector<std::pair<NmtState, NmtState>> changes;
  sensor.onStateChange([&](NmtState from, NmtState to, TimeUs) { changes.emplace_back(from, to); });
  net.startAll();
  net.send("000#0102");
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
  net.send("000#0202");
  EXPECT_EQ(sensor.nmtState(), NmtState::Stopped);
  net.send("000#8002");
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
  net.send("000#0103");  // addressed to node 3
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
  net.send("000#0100");  // broadcast
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
  const std::vector<std::pair<NmtState, NmtState>> expected = {{NmtState::Initialising, NmtState::PreOperational},
                                                               {NmtState::PreOperational, NmtState::Operational},
                                                               {NmtState::Operational, NmtState::Stopped},
                                                               {NmtState::Stopped, NmtState::PreOperational},
                                                               {NmtState::PreOperational, NmtState::Operational}};
  EXPECT_EQ(changes, expected);
}

TEST(Nmt, WrongLengthAndUnknownCommandsAreCountedAndIgnored) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.send("000#01");
  net.send("000#010200");
  EXPECT_EQ(sensor.counters().wrong_length, 2u);
  net.send("000#0302");
  EXPECT_EQ(sensor.counters().nmt_invalid_command, 1u);
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
  net.send("7FF#00");
  EXPECT_EQ(sensor.counters().unknown_cob_id, 1u);
}

TEST(Nmt, StoppedNodeOnlyAnswersNmtAndKeepsItsHeartbeat) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  net.startAll();
  net.send("000#0202");
  EXPECT_EQ(net.exchange("602#4017100000000000"), Frames{});  // SDO is off in Stopped
  net.recorder.log.clear();
  net.bus.advanceBy(100'000);
  EXPECT_EQ(net.recorder.frames(), Frames{"702#04"});
  net.send("000#8002");
  EXPECT_EQ(net.exchange("602#4017100000000000"), Frames{"582#4B17100064000000"});
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
}

TEST(Nmt, ResetCommunicationRestoresCommunicationDefaultsOnly) {
  Network net;
  Node& sensor = net.addEds(odPath("sensor.eds"));
  std::vector<NmtCommand> resets;
  sensor.onReset([&](NmtCommand cmd, TimeUs) { resets.push_back(cmd); });
  net.startAll();
  EXPECT_EQ(net.exchange("602#2B171000F4010000"), Frames{"582#6017100000000000"});  // 0x1017 = 500
  EXPECT_EQ(net.exchange("602#2B00600001000000"), Frames{"582#6000600000000000"});  // 0x6000 = 1
  net.send("000#0102");
  EXPECT_EQ(net.exchange("000#8202"), Frames{"702#00"});
  EXPECT_EQ(sensor.nmtState(), NmtState::PreOperational);
  EXPECT_EQ(sensor.od().entry(0x1017, 0).get<std::uint16_t>(), 100);
  EXPECT_EQ(sensor.od().entry(0x6000, 0).get<std::uint16_t>(), 1);
  EXPECT_EQ(sensor.heartbeatProducer().periodUs(), 100'000);

  EXPECT_EQ(net.exchange("000#8100"), Frames{"702#00"});  // reset node, broadcast
  EXPECT_EQ(sensor.od().entry(0x6000, 0).get<std::uint16_t>(), 0);
  EXPECT_EQ(resets, (std::vector<NmtCommand>{NmtCommand::ResetCommunication, NmtCommand::ResetNode}));
}

TEST(Nmt, MasterCommandsReachOtherNodes) {
  Network net;
  Node& ctrl = net.addEds(odPath("controller.eds"));
  Node& sensor = net.addEds(odPath("sensor.eds"));
  Node& valve = net.addEds(odPath("valve.eds"));
  net.startAll();
  net.recorder.log.clear();
  ASSERT_TRUE(ctrl.sendNmt(NmtCommand::Start, 0));
  net.bus.flush();
  EXPECT_EQ(net.recorder.frames(), Frames{"000#0100"});
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
  EXPECT_EQ(valve.nmtState(), NmtState::Operational);
  EXPECT_EQ(ctrl.nmtState(), NmtState::PreOperational);  // the master switches itself explicitly
  ctrl.applyNmt(NmtCommand::Start);
  EXPECT_EQ(ctrl.nmtState(), NmtState::Operational);
  ctrl.sendNmt(NmtCommand::Stop, 3);
  net.bus.flush();
  EXPECT_EQ(valve.nmtState(), NmtState::Stopped);
  EXPECT_EQ(sensor.nmtState(), NmtState::Operational);
}

}  // namespace
}  // namespace pamc::canopen::test
