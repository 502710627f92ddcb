#include "nodes/virtual_rig.hpp"

#include <time.h>

#include <cerrno>
#include <chrono>
#include <memory>
#include <stdexcept>

#include "canopen/candump_log.hpp"

namespace pamc::nodes {

VirtualRigResult runVirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, double duration_s,
                               const std::string& candump_log, canopen::TimeUs epoch_us, std::uint32_t bitrate,
                               const VirtualRigHooks& hooks) {
  canopen::VirtualBus bus;
  if (bitrate > 0) bus.setBitrate(bitrate);
  auto& cport = bus.addPort();
  auto& eport = bus.addPort();
  auto ctrlp = std::make_unique<ControllerNode>(c, cport, [&bus] { return bus.now(); });  // rings: heap
  auto& ctrl = *ctrlp;
  auto emup = std::make_unique<EmulatorNodes>(e, eport);
  auto& emu = *emup;
  cport.setClient(&ctrl.node());
  eport.setClient(&emu);
  std::unique_ptr<canopen::CandumpWriter> log;
  if (!candump_log.empty()) {
    log = std::make_unique<canopen::CandumpWriter>(candump_log, "vcan0");
    bus.addTap(log->tap(epoch_us));
  }
  if (hooks.tap) bus.addTap(hooks.tap);
  emu.start(bus.now());
  ctrl.start(bus.now());
  VirtualRigResult r;
  const bool forever = hooks.realtime && duration_s <= 0;
  const double limit_s = duration_s + c.preroll_s + 30.0;  // give up if it never starts
  CycleRecord rec;
  using Clock = std::chrono::steady_clock;
  const auto wall0 = Clock::now();
  auto flushed = wall0;
  timespec pace{};
  ::clock_gettime(CLOCK_MONOTONIC, &pace);
  while (forever || ctrl.runTime() < duration_s) {
    bus.advanceBy(1000);
    while (ctrl.records().pop(rec)) {
      if (hooks.on_record) hooks.on_record(rec);
      else r.records.push_back(rec);
    }
    if (!forever && bus.now() * 1e-6 > limit_s) break;
    if (hooks.on_step && !hooks.on_step(bus.now())) break;
    if (log) {
      // A cycle boundary: its lines are complete. Hand them over once per millisecond of wall time.
      const auto now = Clock::now();
      if (hooks.realtime || now - flushed >= std::chrono::milliseconds(1)) {
        log->flush();
        flushed = now;
      }
    }
    if (hooks.realtime) {
      pace.tv_nsec += 1'000'000;
      if (pace.tv_nsec >= 1'000'000'000) pace.tv_nsec -= 1'000'000'000, ++pace.tv_sec;
      while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &pace, nullptr) == EINTR) {
      }
    }
  }
  while (ctrl.records().pop(rec)) {
    if (hooks.on_record) hooks.on_record(rec);
    else r.records.push_back(rec);
  }
  if (log) log->flush();
  r.stats = ctrl.stats();
  r.frames = bus.framesDelivered();
  r.faults = ctrl.faultsRaised();
  r.final_fault = ctrl.fault();
  r.counters = ctrl.node().counters();
  r.bus_busy_us = bus.busyUs();
  return r;
}

}  // namespace pamc::nodes
