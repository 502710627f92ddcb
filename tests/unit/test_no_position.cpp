// A loop that never gets a position says so: one line naming the COB-ID the controller waits for and
// the likely causes, EMCY 0x8250 with the fault's number (Fault::NoPosition), a run that fails at its
// end, and a run that ends on time although the trajectory never started. Two ways to get there on
// the in-process rig: a sensor that is silent from the start, and a sensor whose position TPDO another
// master moved to another COB-ID before the controller started.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "canopen/bus.hpp"
#include "nodes/fault_report.hpp"
#include "plant/plant.hpp"
#include "rig/virtual_rig.hpp"

using namespace pamc;
using canopen::Frame;

namespace {

const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

nodes::ControllerNodeConfig controller(std::vector<std::string>* log) {
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "controller.eds";
  c.kind = static_cast<int>(control::Kind::PI);
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::constant(15.0);
  c.preroll_s = 0.5;
  c.log = [log](const std::string& m) { log->push_back(m); };
  return c;
}

nodes::EmulatorConfig emulator() {
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  return e;
}

// EMCY frames of the controller (0x81): code and the first manufacturer byte (the fault's number).
struct Emcy {
  std::uint16_t code;
  std::uint8_t fault;
};
void collect(std::vector<Emcy>& out, const Frame& f) {
  if (f.id == 0x81 && f.len == 8) out.push_back({canopen::getU16(f.data), f.data[3]});
}
bool has(const std::vector<Emcy>& v, std::uint16_t code, nodes::Fault f) {
  return std::any_of(v.begin(), v.end(),
                     [&](const Emcy& e) { return e.code == code && e.fault == static_cast<std::uint8_t>(f); });
}

void expectTheLine(const std::vector<std::string>& log) {
  const auto it = std::find_if(log.begin(), log.end(),
                               [](const std::string& l) { return l.find("no position") != std::string::npos; });
  ASSERT_NE(it, log.end()) << "no line about the missing position";
  for (const char* what : {"COB-ID 0x182", "node 2", "Operational", "another COB-ID", "mapping", "asynchronous"})
    EXPECT_NE(it->find(what), std::string::npos) << "'" << what << "' missing in: " << *it;
}

}  // namespace

// The sensor never sends (no boot-up, no PDO): the line, the EMCY, the failure, and the run ends by the
// clock at pre-roll + duration + 3 s although the trajectory time never moves.
TEST(NoPosition, ASilentSensorIsReportedAndTheRunEndsOnTime) {
  std::vector<std::string> log;
  std::vector<Emcy> emcy;
  auto e = emulator();
  e.sensor_silent_at_s = 0.0;
  rig::VirtualRigHooks hooks;
  canopen::TimeUs last = 0;
  hooks.tap = [&](const Frame& f, canopen::TimeUs) { collect(emcy, f); };
  hooks.on_step = [&](canopen::TimeUs now) {
    last = now;
    return true;
  };
  const auto r = rig::runVirtualRig(controller(&log), e, 2.0, "", 0, 0, hooks);
  expectTheLine(log);
  EXPECT_TRUE(has(emcy, 0x8250, nodes::Fault::NoPosition)) << "EMCY 0x8250 with fault 19";
  EXPECT_EQ(r.final_fault, nodes::Fault::NoPosition);
  EXPECT_TRUE(r.records.empty());
  EXPECT_NE(r.failure.find("no position in the whole run"), std::string::npos) << r.failure;
  EXPECT_NE(r.failure.find("0x182"), std::string::npos) << r.failure;
  EXPECT_LE(last, 5'500'000) << "ends at pre-roll 0.5 + duration 2 + 3 s";
  EXPECT_GE(last, 5'400'000);
}

// Another master moved the sensor's TPDO to 0x190 before the controller started: the controller (no rig
// file, so it configures nothing) waits on 0x182. The line names 0x182; the fault comes 1 s after
// Operational; moved back, the loop starts and the fault clears.
TEST(NoPosition, ATpdoMovedBeforeTheStartIsReportedWithTheCobIdAwaited) {
  std::vector<std::string> log;
  std::vector<Emcy> emcy;
  rig::VirtualRig rig(controller(&log), emulator());
  rig.addTap([&](const Frame& f, canopen::TimeUs) { collect(emcy, f); });
  auto& port = rig.addPort();
  auto move = [&](std::uint32_t from, std::uint32_t to) {
    for (std::uint32_t v : {from | 0x80000000u, to}) {
      std::uint8_t d[8] = {0x23, 0x00, 0x18, 0x01};
      canopen::putU32(d + 4, v);
      port.send(canopen::makeFrame(0x602, 8, d));
      rig.bus().flush();
    }
  };
  rig.startEmulator();
  rig.bus().flush();
  move(0x182, 0x190);
  ASSERT_EQ(rig.emulator().sensor().od().find(0x1800, 1)->get<std::uint32_t>(), 0x190u);
  rig.startController();
  rig.runFor(0.95);
  EXPECT_EQ(rig.controller().fault(), nodes::Fault::None) << "not before 1 s";
  rig.runFor(0.1);
  EXPECT_EQ(rig.controller().fault(), nodes::Fault::NoPosition);
  expectTheLine(log);
  EXPECT_TRUE(has(emcy, 0x8250, nodes::Fault::NoPosition));
  EXPECT_FALSE(rig.controller().running());
  EXPECT_TRUE(nodes::runFailure(rig.controller()).has_value());
  move(0x190, 0x182);
  rig.runFor(1.5);
  EXPECT_EQ(rig.controller().fault(), nodes::Fault::None) << "recovered once positions come";
  EXPECT_TRUE(rig.controller().running());
  EXPECT_FALSE(nodes::runFailure(rig.controller()).has_value());
  EXPECT_NE(std::find_if(emcy.begin(), emcy.end(), [](const Emcy& x) { return x.code == 0; }), emcy.end())
      << "EMCY reset after the recovery";
}

// A run that ends normally is bounded by its trajectory time, not by the clock's deadline.
TEST(NoPosition, ANormalRunEndsAfterItsTrajectory) {
  std::vector<std::string> log;
  const auto r = rig::runVirtualRig(controller(&log), emulator(), 1.0);
  EXPECT_TRUE(r.failure.empty()) << r.failure;
  ASSERT_FALSE(r.records.empty());
  EXPECT_NEAR(r.records.back().t, 1.0, 0.002);
  EXPECT_TRUE(log.empty()) << log.front();
}
