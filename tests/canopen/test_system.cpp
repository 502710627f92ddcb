// The three project nodes (controller, sensor, valve) together on the in-process bus.
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <new>
#include <sstream>

#include "../common/count_allocations.hpp"
#include "test_util.hpp"

namespace pamc::canopen::test {
namespace {

using Frames = std::vector<std::string>;

// The application side of each node, as the pamc programs would write it.
struct System {
  explicit System(VirtualBus& bus) {
    auto attach = [&](const char* eds) -> Node& {
      VirtualBus::Port& port = bus.addPort();
      nodes.push_back(Node::fromEds(odPath(eds), port));
      port.setClient(nodes.back().get());
      return *nodes.back();
    };
    ctrl = &attach("controller.eds");
    sensor = &attach("sensor.eds");
    valve = &attach("valve.eds");

    // Resolved once; the callbacks below only call get/set.
    ctrl_pos = ctrl->od().ref<std::int32_t>(0x3000, 0);
    ctrl_cmd = ctrl->od().ref<std::int16_t>(0x3002, 0);
    sensor_pos = sensor->od().ref<std::int32_t>(0x6004, 0);
    valve_cmd = valve->od().ref<std::int16_t>(0x6411, 1);
    valve_pressure = valve->od().ref<std::int16_t>(0x6401, 1);

    ctrl->onSync([this](std::uint8_t, TimeUs) {
      ++ctrl_cycles;
      ctrl_seen = ctrl_pos.get();
      ctrl_cmd.set(static_cast<std::int16_t>(ctrl_cycles));  // command = cycle number, to trace the pipeline
    });
    sensor->onSync([this](std::uint8_t, TimeUs) {
      ++sensor_cycles;
      sensor_pos.set(static_cast<std::int32_t>(5000 + 7 * sensor_cycles));
    });
    valve->onSync([this](std::uint8_t, TimeUs) {
      valve_applied = valve_cmd.get();
      valve_pressure.set(valve_applied);
    });
  }

  void start(VirtualBus& bus) {
    for (auto& n : nodes) n->start(bus.now());
    bus.flush();
    ctrl->sendNmt(NmtCommand::Start, 0);  // NMT master starts everyone, then itself
    ctrl->applyNmt(NmtCommand::Start);
    bus.flush();
  }

  std::vector<std::unique_ptr<Node>> nodes;
  Node* ctrl = nullptr;
  Node* sensor = nullptr;
  Node* valve = nullptr;
  Ref<std::int32_t> ctrl_pos, sensor_pos;
  Ref<std::int16_t> ctrl_cmd, valve_cmd, valve_pressure;
  std::int64_t ctrl_cycles = 0, sensor_cycles = 0;
  std::int32_t ctrl_seen = 0;
  std::int16_t valve_applied = 0;
};

TEST(System, ControllerSensorValvePipeline) {
  VirtualBus bus;
  Recorder rec(bus);
  System sys(bus);
  sys.start(bus);
  EXPECT_EQ(rec.take(), (Frames{"701#00", "702#00", "703#00", "000#0100"}));
  for (auto& n : sys.nodes) EXPECT_EQ(n->nmtState(), NmtState::Operational);

  bus.advanceTo(1'000);  // SYNC 1
  EXPECT_EQ(rec.take(), (Frames{"080#", "203#0100", "182#8F130000", "183#0000"}));
  bus.advanceTo(2'000);  // SYNC 2: valve applies command 1, controller sees sensor's first position
  EXPECT_EQ(rec.take(), (Frames{"080#", "203#0200", "182#96130000", "183#0100"}));
  EXPECT_EQ(sys.ctrl_seen, 5007);
  EXPECT_EQ(sys.valve_applied, 1);
  EXPECT_EQ(sys.ctrl->od().entry(0x3001, 0).get<std::int16_t>(), 0);  // pressure of cycle 1

  bus.advanceTo(50'000);
  // Every cycle: the controller sees the position sent one SYNC earlier and the valve applies the
  // command computed one SYNC earlier.
  EXPECT_EQ(sys.ctrl_cycles, 50);
  EXPECT_EQ(sys.ctrl_seen, 5000 + 7 * 49);
  EXPECT_EQ(sys.valve_applied, 49);
  EXPECT_EQ(sys.ctrl->od().entry(0x3001, 0).get<std::int16_t>(), 48);
  EXPECT_EQ(sys.ctrl->rpdo(1).syncsSinceReception(), 0u);
  for (auto& n : sys.nodes) {
    EXPECT_EQ(n->counters().wrong_length, 0u);
    EXPECT_EQ(n->counters().tx_dropped, 0u);
  }
}

TEST(System, MissingSensorPdosAreCountedPerCycle) {
  VirtualBus bus;
  System sys(bus);
  std::vector<std::pair<std::uint8_t, HeartbeatEvent>> events;
  sys.ctrl->onHeartbeat([&](std::uint8_t node, HeartbeatEvent e, NmtState, TimeUs) { events.emplace_back(node, e); });
  sys.start(bus);
  bus.advanceTo(10'500);
  sys.ctrl->sendNmt(NmtCommand::Stop, 2);
  bus.advanceBy(4'000);
  EXPECT_EQ(sys.ctrl->rpdo(1).syncsSinceReception(), 3u);
  EXPECT_EQ(sys.ctrl->rpdo(2).syncsSinceReception(), 0u);
  bus.advanceTo(1'000'000);
  // The stopped sensor still sends heartbeats (its first one already says Stopped): no timeout.
  const std::vector<std::pair<std::uint8_t, HeartbeatEvent>> expected = {{2, HeartbeatEvent::BootUp},
                                                                         {3, HeartbeatEvent::BootUp},
                                                                         {2, HeartbeatEvent::Started},
                                                                         {3, HeartbeatEvent::Started}};
  EXPECT_EQ(events, expected);
  EXPECT_EQ(sys.ctrl->heartbeatConsumer().remoteState(2), NmtState::Stopped);
}

TEST(System, DeterministicAndFasterThanRealTime) {
  auto run = [](TimeUs duration_us) {
    std::ostringstream log;
    VirtualBus bus;
    CandumpWriter writer(log, "vcan0");
    bus.addTap(writer.tap(1700000000000000));
    System sys(bus);
    sys.start(bus);
    bus.advanceTo(duration_us);
    writer.flush();
    return log.str();
  };
  auto t0 = std::chrono::steady_clock::now();
  std::string a = run(10'000'000);  // 10 s of bus time
  auto wall = std::chrono::steady_clock::now() - t0;
  std::string b = run(10'000'000);
  EXPECT_EQ(a, b);
  EXPECT_EQ(std::count(a.begin(), a.end(), '\n'), 4 + 10'000 * 4 + 3 * 100);  // + heartbeats
  EXPECT_LT(std::chrono::duration<double>(wall).count(), 5.0);
}

TEST(System, CyclicPathDoesNotAllocate) {
  if (!PAMC_COUNT_ALLOCATIONS) GTEST_SKIP() << "allocation counting is off under AddressSanitizer";
  VirtualBus bus;
  System sys(bus);
  sys.start(bus);
  bus.advanceTo(200'000);  // warm up: every service has run
  long allocations = 0;
  {
    pamc::test::CountAllocations c;
    bus.advanceTo(1'200'000);  // 1000 SYNC cycles, heartbeats, PDOs both ways
    sys.ctrl->sendNmt(NmtCommand::Stop, 2);
    bus.advanceTo(1'210'000);
    allocations = c.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(sys.ctrl_cycles, 1210);
}

}  // namespace
}  // namespace pamc::canopen::test
