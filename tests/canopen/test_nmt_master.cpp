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
    net.recorder.log.clear();
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
  EXPECT_EQ(r.master.counters().starts, 1u);
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
  EXPECT_TRUE(r.master.down(2, t0 + NmtMaster::kStartGraceUs)) << "did not follow the start";
  r.net.bus.flush();
  EXPECT_EQ(r.nmt(), Frames{"000#0102"}) << "another start";
  r.net.send("702#04");
  EXPECT_EQ(r.seen.back(), (Seen{2, SlaveEvent::Stopped}));
  EXPECT_TRUE(r.master.down(2, r.net.bus.now()));
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
