// The controller node's SYNC-to-setpoint path on the in-process bus, with and without background
// traffic, and the bus load of a cycle. Run: build/tests/bench/pamc_bench_can
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <thread>
#include <vector>

#include "nodes/controller_node.hpp"
#include "nodes/emulator_node.hpp"
#include "canopen/frame_bits.hpp"
#include "nodes/rig_file.hpp"
#include "rig/rig_emulator.hpp"
#include "rig/virtual_rig.hpp"

using namespace pamc;

namespace {
const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

nodes::ControllerNodeConfig ctrlConfig(control::Kind kind) {
  nodes::ControllerNodeConfig c;
  c.eds_path = kOd + "controller.eds";
  c.kind = static_cast<int>(kind);
  c.gains_from_config = true;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::triangle(0.05, 0.2, 30.0);
  c.preroll_s = 0.5;
  c.ctrl.model = model::Model({9.0, 1.6, 17.0, 1.0, 0.4, 0.5});
  return c;
}

nodes::EmulatorConfig emuConfig() {
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  return e;
}

// The four-muscle rig (od/rigs/four_muscles.ini): its controller and emulator configurations.
nodes::ControllerNodeConfig fourMuscles(control::Kind kind, nodes::EmulatorConfig& e) {
  const auto rf = nodes::readRigFile(kOd + "rigs/four_muscles.ini");
  auto c = ctrlConfig(kind);
  nodes::applyRig(rf, c);
  e = rig::emulatorOf(rf, emuConfig());
  return c;
}

// Wall-clock time of the SYNC path of the controller node: SYNC frame in -> RPDOs latched ->
// estimator and controller -> valve setpoint TPDO handed to the transport. `background` frames of
// other COB-IDs (higher priority than the position PDO) reach the node each cycle. four: the node of
// four channels (od/rigs/four_muscles.ini).
void syncToSetpoint(benchmark::State& state, control::Kind kind, int background, bool four = false) {
  nodes::EmulatorConfig e = emuConfig();
  const auto c = four ? fourMuscles(kind, e) : ctrlConfig(kind);
  rig::VirtualRig rig(c, e);
  rig.setRecordSink([](const nodes::CycleRecord&) {});
  auto& bus = rig.bus();
  auto& ctrl = rig.controller();
  rig.start();
  rig.runFor(1.0);  // boot, NMT, first cycles
  // The node produces the SYNC itself: time its advance() at the SYNC deadline, which sends the
  // SYNC, latches the RPDOs, runs the cycle and hands the setpoint TPDO to the transport.
  std::vector<double> ns;
  ns.reserve(1 << 20);
  canopen::Frame bg;
  bg.id = 0x050;  // higher priority than every PDO, unknown to the node: counted and ignored
  bg.len = 8;
  for (auto _ : state) {
    const canopen::TimeUs deadline = ctrl.node().nextDeadline();
    bus.advanceTo(deadline - 1);
    for (int i = 0; i < background; ++i) ctrl.node().onFrame(bg, bus.now());
    const auto t0 = std::chrono::steady_clock::now();
    ctrl.node().advance(deadline);
    const auto t1 = std::chrono::steady_clock::now();
    ns.push_back(std::chrono::duration<double, std::nano>(t1 - t0).count());
    bus.advanceTo(deadline);
  }
  std::sort(ns.begin(), ns.end());
  state.counters["median_us"] = ns[ns.size() / 2] * 1e-3;
  state.counters["p99_us"] = ns[std::min(ns.size() - 1, ns.size() * 99 / 100)] * 1e-3;
  state.counters["max_us"] = ns.back() * 1e-3;
}

void BM_SyncToSetpoint_PI(benchmark::State& s) { syncToSetpoint(s, control::Kind::PI, 0); }
void BM_SyncToSetpoint_AMC(benchmark::State& s) { syncToSetpoint(s, control::Kind::PiAmc, 0); }
void BM_SyncToSetpoint_AMC_Traffic(benchmark::State& s) { syncToSetpoint(s, control::Kind::PiAmc, 50); }
void BM_SyncToSetpoint_PI_FourChannels(benchmark::State& s) { syncToSetpoint(s, control::Kind::PI, 0, true); }
void BM_SyncToSetpoint_AMC_FourChannels(benchmark::State& s) { syncToSetpoint(s, control::Kind::PiAmc, 0, true); }

// What an SDO commit (0x2003:01 = 1) costs the thread that runs the node: the request frame handled -
// values checked and, inline, the new controller built - in the time between two cycles. With the
// build off the cycle (pamc controller) only the checks remain; the worker builds, the next cycle
// boundary after it takes the set.
void sdoCommit(benchmark::State& state, control::Kind kind, bool off_cycle) {
  auto c = ctrlConfig(kind);
  c.build_off_cycle = off_cycle;
  rig::VirtualRig rig(c, emuConfig());
  rig.setRecordSink([](const nodes::CycleRecord&) {});
  auto& ctrl = rig.controller();
  rig.start();
  rig.runFor(1.0);
  const std::uint8_t d[8] = {0x2F, 0x03, 0x20, 0x01, 1, 0, 0, 0};
  const canopen::Frame commit = canopen::makeFrame(0x601, 8, d);
  std::vector<double> ms;
  for (auto _ : state) {
    const std::uint64_t applied = ctrl.faultCounters().sets_applied;
    const auto t0 = std::chrono::steady_clock::now();
    ctrl.node().onFrame(commit, rig.bus().now());
    const auto t1 = std::chrono::steady_clock::now();
    const double t = std::chrono::duration<double>(t1 - t0).count();
    state.SetIterationTime(t);
    ms.push_back(t * 1e3);
    while (ctrl.faultCounters().sets_applied == applied) {  // until the set is taken (not timed)
      if (off_cycle) std::this_thread::sleep_for(std::chrono::microseconds(200));
      rig.step();
    }
  }
  std::sort(ms.begin(), ms.end());
  state.counters["median_ms"] = ms[ms.size() / 2];
  state.counters["max_ms"] = ms.back();
}
void BM_SdoCommit_OpenLoop_Inline(benchmark::State& s) { sdoCommit(s, control::Kind::OpenLoop, false); }
void BM_SdoCommit_OpenLoop_OffCycle(benchmark::State& s) { sdoCommit(s, control::Kind::OpenLoop, true); }
void BM_SdoCommit_AMC_Inline(benchmark::State& s) { sdoCommit(s, control::Kind::PiAmc, false); }
void BM_SdoCommit_AMC_OffCycle(benchmark::State& s) { sdoCommit(s, control::Kind::PiAmc, true); }

// A whole 1 ms cycle of the rig on the in-process bus (SYNC, 3 PDOs, heartbeats, both node sides,
// emulator physics, AMC): how much faster than real time the CAN-level simulation runs.
void BM_RigCycle(benchmark::State& state) {
  rig::VirtualRig rig(ctrlConfig(control::Kind::PiAmc), emuConfig());
  rig.setRecordSink([](const nodes::CycleRecord&) {});
  rig.start();
  for (auto _ : state) rig.step();
  state.counters["x_realtime"] =
      benchmark::Counter(1e-3 * static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}

// Bits on the wire per cycle against the 1 ms period at 1 Mbit/s.
void BM_BusLoadPerCycle(benchmark::State& state) {
  rig::VirtualRig rig(ctrlConfig(control::Kind::PI), emuConfig());
  rig.setRecordSink([](const nodes::CycleRecord&) {});
  auto& bus = rig.bus();
  double bits = 0;
  std::uint64_t frames = 0;
  bus.addTap([&](const canopen::Frame& f, canopen::TimeUs) {
    bits += canopen::frameBits(f);
    ++frames;
  });
  rig.start();
  rig.runFor(1.0);
  bits = 0;
  frames = 0;
  std::uint64_t cycles = 0;
  for (auto _ : state) {
    rig.step();
    ++cycles;
  }
  const double per = bits / static_cast<double>(cycles);
  state.counters["frames_per_cycle"] = static_cast<double>(frames) / static_cast<double>(cycles);
  state.counters["bits_per_cycle"] = per;
  state.counters["us_at_1Mbit"] = per;  // 1 bit = 1 us at 1 Mbit/s
  state.counters["load_pct_1kHz"] = per / 1000.0 * 100.0;
}
}  // namespace

BENCHMARK(BM_SyncToSetpoint_PI)->Iterations(20000);
BENCHMARK(BM_SyncToSetpoint_AMC)->Iterations(20000);
BENCHMARK(BM_SyncToSetpoint_AMC_Traffic)->Iterations(20000);
BENCHMARK(BM_SyncToSetpoint_PI_FourChannels)->Iterations(20000);
BENCHMARK(BM_SyncToSetpoint_AMC_FourChannels)->Iterations(20000);
BENCHMARK(BM_RigCycle);
BENCHMARK(BM_SdoCommit_OpenLoop_Inline)->UseManualTime()->Iterations(30)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SdoCommit_OpenLoop_OffCycle)->UseManualTime()->Iterations(30)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SdoCommit_AMC_Inline)->UseManualTime()->Iterations(30)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SdoCommit_AMC_OffCycle)->UseManualTime()->Iterations(30)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_BusLoadPerCycle)->Iterations(10000);

BENCHMARK_MAIN();
