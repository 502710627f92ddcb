#include "rig/virtual_rig.hpp"

#include <time.h>

#include <cerrno>
#include <chrono>
#include <memory>
#include <stdexcept>

#include "canopen/candump_log.hpp"

namespace pamc::rig {

using namespace nodes;

VirtualRig::VirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, std::uint32_t bitrate,
                       FrameEdit emulator_tx)
    : cport_(bus_.addPort()), eport_(bus_.addPort()), etx_(eport_, std::move(emulator_tx)), reporter_(c.log) {
  if (bitrate > 0) bus_.setBitrate(bitrate);
  ctrl_ = std::make_unique<ControllerNode>(c, cport_, [this] { return bus_.now(); });
  emu_ = std::make_unique<EmulatorNodes>(e, etx_);
  cport_.setClient(&ctrl_->node());
  eport_.setClient(emu_.get());
}

void VirtualRig::start() {
  startEmulator();
  startController();
}
void VirtualRig::startEmulator() { emu_->start(bus_.now()); }
void VirtualRig::startController() { ctrl_->start(bus_.now()); }

void VirtualRig::step(canopen::TimeUs dt_us) {
  bus_.advanceBy(dt_us);
  CycleRecord rec;
  while (ctrl_->records().pop(rec)) {
    if (sink_)
      sink_(rec);
    else
      records_.push_back(rec);
  }
  reporter_.step(*ctrl_);
}

VirtualRigResult runVirtualRig(const ControllerNodeConfig& c, const EmulatorConfig& e, double duration_s,
                               const std::string& candump_log, canopen::TimeUs epoch_us, std::uint32_t bitrate,
                               const VirtualRigHooks& hooks) {
  VirtualRig rig(c, e, bitrate);
  auto& bus = rig.bus();
  auto& ctrl = rig.controller();
  VirtualRigResult r;
  if (hooks.on_record) rig.setRecordSink(hooks.on_record);
  std::unique_ptr<canopen::CandumpWriter> log;
  if (!candump_log.empty()) {
    log = std::make_unique<canopen::CandumpWriter>(candump_log, "vcan0");
    bus.addTap(log->tap(epoch_us));
  }
  if (hooks.tap) bus.addTap(hooks.tap);
  rig.start();
  const bool forever = (hooks.realtime || hooks.until_stopped) && duration_s <= 0;
  const RunEnd end(duration_s, c.preroll_s, bus.now());
  using Clock = std::chrono::steady_clock;
  const auto wall0 = Clock::now();
  auto flushed = wall0;
  timespec pace{};
  ::clock_gettime(CLOCK_MONOTONIC, &pace);
  while (forever || (duration_s > 0 && !end.reached(ctrl, bus.now()))) {
    rig.step();
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
      timespec woke{};
      ::clock_gettime(CLOCK_MONOTONIC, &woke);
      const double late_us = static_cast<double>(woke.tv_sec - pace.tv_sec) * 1e6 +
                             static_cast<double>(woke.tv_nsec - pace.tv_nsec) * 1e-3;
      r.wake_late_us.add(late_us);
      if (late_us >= 1000.0) ++r.wake_overruns;
    }
  }
  rig.step(0);  // the records of the last cycle
  r.records = std::move(rig.records());
  if (log) log->flush();
  r.stats = ctrl.stats();
  r.frames = bus.framesDelivered();
  r.faults = ctrl.faultsRaised();
  r.final_fault = ctrl.fault();
  r.counters = ctrl.node().counters();
  r.bus_busy_us = bus.busyUs();
  if (auto why = runFailure(ctrl)) r.failure = *why;
  return r;
}

}  // namespace pamc::rig
