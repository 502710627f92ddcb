// Controller and emulator as CANopen nodes on the in-process bus, against the lockstep simulation.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>

#include "canopen/candump_log.hpp"
#include "control/actuation.hpp"
#include "control/controller.hpp"
#include "plant/plant.hpp"
#include "rig/virtual_rig.hpp"
#include "sim/lockstep.hpp"

using namespace pamc;

namespace {
const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

nodes::ControllerNodeConfig controllerConfig(control::Kind kind, const control::Trajectory& traj) {
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "controller.eds";
  c.kind = static_cast<int>(kind);
  c.gains_from_config = true;
  c.has_trajectory = true;
  c.trajectory = traj;
  c.preroll_s = 5.0;
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;  // a model with every effect: exercises the most
  return c;
}

nodes::EmulatorConfig emulatorConfig() {
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  return e;
}

double rmse(const std::vector<double>& a, const std::vector<double>& b) {
  double s = 0;
  for (size_t i = 0; i < a.size(); ++i) s += (a[i] - b[i]) * (a[i] - b[i]);
  return std::sqrt(s / static_cast<double>(a.size()));
}
}  // namespace

class RigMatchesLockstep : public ::testing::TestWithParam<control::Kind> {};

// The same controller on the same emulator, once through the CANopen layer and once in lockstep
// (delay_cycles = 2): tracking RMSE within 1 % of each other. (Start-up differs by a few cycles -
// the rig waits for the first position PDO - so the traces are close, not identical; the timing
// itself is pinned by RigTiming below.)
TEST_P(RigMatchesLockstep, TrackingRmseAgrees) {
  const auto traj = control::Trajectory::triangle(0.1, 5.0, 25.0);
  const double duration = 10.0;
  auto cc = controllerConfig(GetParam(), traj);
  const auto rig = rig::runVirtualRig(cc, emulatorConfig(), duration);
  ASSERT_GE(rig.records.size(), 9990u);
  EXPECT_EQ(rig.faults, 0u);
  std::vector<double> e_rig;
  for (const auto& r : rig.records) e_rig.push_back(r.yd - r.y);
  control::ControllerConfig lc = cc.ctrl;
  lc.delay_cycles = 2;
  auto ctrl = control::makeController(GetParam(), lc);
  plant::Plant p(emulatorConfig().plant);
  sim::ClosedLoopRun run;
  run.reference = traj;
  run.duration_s = duration;
  run.preroll_s = cc.preroll_s;
  run.delay_cycles = 2;
  const auto rec = sim::runClosedLoop(*ctrl, p, run, -5.0);
  std::vector<double> e_ls;
  for (size_t i = 0; i < rec.t.size(); ++i) e_ls.push_back(rec.yd[i] - rec.y[i]);
  const double r_rig = rmse(e_rig, std::vector<double>(e_rig.size(), 0.0));
  const double r_ls = rmse(e_ls, std::vector<double>(e_ls.size(), 0.0));
  EXPECT_NEAR(r_rig, r_ls, 0.01 * r_ls) << "rig " << r_rig << " lockstep " << r_ls;
  EXPECT_GT(r_ls, 0.01);  // a real run, not a flat line
}

namespace {
// Cycles from the first command jump after the start until the position moves.
int cyclesUntilResponse(const std::vector<double>& u, const std::vector<double>& y) {
  for (size_t i = 10; i + 6 < u.size(); ++i) {
    if (std::fabs(u[i] - u[i - 1]) < 0.1) continue;
    for (size_t k = i + 1; k < i + 6; ++k)
      if (std::fabs(y[k] - y[k - 1]) > 0.01) return static_cast<int>(k - i);
    return -1;
  }
  return -2;
}
}  // namespace

// The pipeline, cycle for cycle: a command computed at SYNC k first shows in the position the
// controller latches at SYNC k+3 (valve applies it at k+1, sensor samples at k+2, controller
// latches at k+3) - on the bus and in the lockstep simulation with delay_cycles = 2.
TEST(RigTiming, CommandShowsInThePositionThreeCyclesLater) {
  const auto traj = control::Trajectory::square(0.5, 10.0, 20.0);
  auto cc = controllerConfig(control::Kind::OpenLoop, traj);
  cc.preroll_s = 3.0;
  auto ec = emulatorConfig();
  // No inertia or friction and a fast pressure, so the first sample after the command moves visibly.
  ec.plant = plant::PlantConfig::fromJson(
      nlohmann::json::parse(
          R"({"kind":"model","effects":{"mass_spring":{"enabled":false},"friction_hysteresis":{"enabled":false},)"
          R"("pressure_lag":{"tau":0.04}}})"),
      "test");
  ec.plant.sensor_noise = false;
  cc.ctrl.model = ec.plant.truth;
  const auto rig = rig::runVirtualRig(cc, ec, 2.0);
  std::vector<double> u, y;
  for (const auto& r : rig.records) u.push_back(r.u), y.push_back(r.y);
  EXPECT_EQ(cyclesUntilResponse(u, y), 3);

  control::ControllerConfig lc = cc.ctrl;
  auto ctrl = control::makeController(control::Kind::OpenLoop, lc);
  plant::Plant p(ec.plant);
  sim::ClosedLoopRun run;
  run.reference = traj;
  run.duration_s = 2.0;
  run.preroll_s = 3.0;
  run.delay_cycles = 2;
  const auto rec = sim::runClosedLoop(*ctrl, p, run, -5.0);
  EXPECT_EQ(cyclesUntilResponse(rec.u, rec.y), 3);
}

INSTANTIATE_TEST_SUITE_P(Controllers, RigMatchesLockstep,
                         ::testing::Values(control::Kind::PI, control::Kind::PidEso, control::Kind::PiAmc),
                         [](const auto& info) { return std::string(control::toString(info.param)); });

TEST(Rig, CandumpLogOfTheRunDecodesBack) {
  const std::string log = ::testing::TempDir() + "/pamc_rig.log";
  const auto rig = rig::runVirtualRig(controllerConfig(control::Kind::PI, control::Trajectory::constant(15.0)),
                                      emulatorConfig(), 1.0, log);
  const auto frames = canopen::readCandumpLog(log);
  ASSERT_GT(frames.size(), 3 * 6000u);  // SYNC + position + setpoint + pressure per cycle, 6 s
  // Boot-ups, NMT start, SYNCs at 1 ms.
  int syncs = 0, boot = 0, nmt = 0;
  for (const auto& f : frames) {
    syncs += f.frame.id == 0x80;
    boot += f.frame.id >= 0x701 && f.frame.id <= 0x703 && f.frame.len == 1 && f.frame.data[0] == 0;
    nmt += f.frame.id == 0x000;
  }
  EXPECT_EQ(boot, 3);
  EXPECT_GE(nmt, 2);
  EXPECT_GT(syncs, 6000);
}

TEST(Rig, SensorSilenceDrivesTheValveSafeAndSendsEmcy) {
  auto e = emulatorConfig();
  e.sensor_silent_at_s = 7.0;  // 2 s into the run after the 5 s pre-roll
  const std::string log = ::testing::TempDir() + "/pamc_silent.log";
  const auto rig =
      rig::runVirtualRig(controllerConfig(control::Kind::PI, control::Trajectory::constant(15.0)), e, 4.0, log);
  EXPECT_GE(rig.faults, 1u);
  // After the fault, every record has the safe command (0 V = -5 V relative) and a fault code.
  size_t first = 0;
  for (size_t i = 0; i < rig.records.size(); ++i)
    if (rig.records[i].fault != 0) {
      first = i;
      break;
    }
  ASSERT_GT(first, 0u);
  const auto f = static_cast<nodes::Fault>(rig.records[first].fault);
  EXPECT_EQ(f, nodes::Fault::PositionMissing);  // 3 missing PDOs come before the 250 ms heartbeat timeout
  for (size_t i = first; i < rig.records.size(); ++i) EXPECT_DOUBLE_EQ(rig.records[i].u, -5.0);
  // The controller's EMCY (0x81) with the RPDO-timeout code 0x8250.
  bool emcy = false;
  for (const auto& r : canopen::readCandumpLog(log))
    if (r.frame.id == 0x81 && r.frame.len == 8 && r.frame.data[0] == 0x50 && r.frame.data[1] == 0x82) emcy = true;
  EXPECT_TRUE(emcy);
}

// With 1 Mbit/s bit timing and arbitration the frames of a cycle take ~280 us of the 1000 us period and
// all arrive before the next SYNC: the same cycle, the same result as on the ideal bus.
TEST(RigTiming, OneMegabitBusKeepsTheCycle) {
  const auto traj = control::Trajectory::triangle(0.1, 5.0, 25.0);
  auto cc = controllerConfig(control::Kind::PI, traj);
  cc.preroll_s = 1.0;
  const auto ideal = rig::runVirtualRig(cc, emulatorConfig(), 3.0);
  const auto timed = rig::runVirtualRig(cc, emulatorConfig(), 3.0, "", 1700000000000000, 1'000'000);
  EXPECT_EQ(timed.faults, 0u);
  EXPECT_EQ(timed.counters.rpdo_late, 0u);
  EXPECT_EQ(timed.counters.tx_dropped, 0u);
  ASSERT_EQ(timed.records.size(), ideal.records.size());
  double worst = 0;
  for (size_t i = 0; i < ideal.records.size(); ++i)
    worst = std::max(worst, std::fabs(timed.records[i].y - ideal.records[i].y));
  EXPECT_LT(worst, 1e-9);
  const double load = static_cast<double>(timed.bus_busy_us) / (timed.stats.cycles * 1000.0);
  EXPECT_GT(load, 0.2);
  EXPECT_LT(load, 0.35);
}

// --input on the rig: no controller, the input spec's value goes to the valve within the valve's range
// (recorded u = clamp(input(t))), and the position recorded is the plant's answer to that command - the
// same command replayed through the plant in lockstep, three cycles earlier on the bus (RigTiming).
TEST(RigInput, CommandIsTheInputClampedAndThePositionThePlants) {
  const auto input = control::Trajectory::parse("random:1:-7:7");  // beyond the valve's range on both sides
  auto cc = controllerConfig(control::Kind::Input, input);
  const auto rig = rig::runVirtualRig(cc, emulatorConfig(), 20.0);
  ASSERT_GE(rig.records.size(), 19990u);
  EXPECT_EQ(rig.faults, 0u);
  int clamped = 0;
  std::vector<double> u, y;
  for (const auto& r : rig.records) {
    const double want = std::clamp(input.at(r.t), control::kCommandMin, control::kCommandMax);
    ASSERT_EQ(r.u, want) << "t " << r.t;
    ASSERT_EQ(r.yd, input.at(r.t));
    clamped += r.u != r.yd;
    u.push_back(r.u);
    y.push_back(r.y);
  }
  EXPECT_GT(clamped, 1000);
  plant::Plant p(emulatorConfig().plant);
  const auto ls = sim::runOpenLoopSamples(p, u);
  constexpr std::size_t kLag = 3;  // y of record k+3 was sampled after u_k was held for one cycle
  std::vector<double> y_rig(y.begin() + kLag, y.end()), y_ls(ls.y.begin(), ls.y.end() - kLag);
  const auto [lo, hi] = std::minmax_element(y_ls.begin(), y_ls.end());
  const double e = rmse(y_rig, y_ls);
  EXPECT_GT(*hi - *lo, 10.0);  // the input moves the muscle over much of its stroke
  EXPECT_LT(e, 0.01 * (*hi - *lo)) << "rig against lockstep: RMSE " << e << " mm over a span of " << *hi - *lo;
}
