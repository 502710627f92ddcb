// The controller node's cycle: what the SYNC callback runs, in order, across the channels - each one's
// drivers, fault supervisor and control loop. Set-up and hooks are in controller_node_setup.cpp.
#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>

namespace pamc::nodes {

using canopen::TimeUs;

// The loop's command, with a joint's co-contraction on top while the loop runs (not the safe value).
double ControllerNode::Channel::command() const noexcept {
  const double u = loop->command();
  if (offset_v == 0.0 || faults->fault() != Fault::None || !loop->active()) return u;
  return std::clamp(u + offset_v, pd::kCommandMin, pd::kCommandMax);
}

// ---- Faults ----------------------------------------------------------------------------------------

void ControllerNode::takeCauses(Channel& c, TimeUs now) noexcept {
  if (!c.faults->takeCauses(now)) return;
  // The safe state begins: the loop's command is the safe value, which send() gives the valve in this
  // cycle's TPDO (the one write of the cycle).
  c.loop->enterSafe(params_->safeCommand());
}

void ControllerNode::recover(Channel& c, double y, TimeUs now) noexcept {
  c.faults->recover();
  c.valve->release(ValveDriver::kHoldCollision, now);
  c.loop->recoverFrom(y, params_->safeCommand());
}

// A cause of the bus or of the node itself: every channel meets it (one reports it).
void ControllerNode::raiseAll(Fault f, std::uint8_t detail) noexcept {
  for (auto& c : channels_) c.faults->raise(f, detail);
}

void ControllerNode::holdValves(std::uint8_t reason) noexcept {
  for (auto& c : channels_) c.valve->hold(reason);
}

void ControllerNode::releaseValves(std::uint8_t reason, TimeUs now) noexcept {
  for (auto& c : channels_) c.valve->release(reason, now);
}

// Every fault cause of a channel, every cycle: its sensor's and its valve's, then the bus's.
void ControllerNode::poll(Channel& c, TimeUs now) noexcept {
  DriverCycle dc;
  dc.now = now;
  dc.active = c.loop->active();
  dc.usable = c.sample.usable();
  dc.cycle = c.loop->cycle();
  dc.ps = &params_->running();
  dc.Ts = c.loop->period();
  c.sensor->supervise(*c.faults, dc);
  c.valve->supervise(*c.faults, dc);
  c.faults->pollBus();
}

// A channel in its safe state by a cause of its own takes its joint partner along (every channel
// with faults = all), in the same cycle.
void ControllerNode::spreadFaults() noexcept {
  if (channels_.size() < 2) return;
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    if (!channels_[i].faults->spreads()) continue;
    for (std::size_t j = 0; j < channels_.size(); ++j) {
      if (j == i || !(fault_all_ || channels_[i].partner == static_cast<int>(j))) continue;
      channels_[j].faults->raise(Fault::OtherChannel, static_cast<std::uint8_t>(i + 1));
      takeCauses(channels_[j], node_->now());
    }
  }
}

// ---- The cycle -------------------------------------------------------------------------------------

void ControllerNode::onSync(std::uint8_t, TimeUs now) noexcept {
  measurePeriod(now);
  releaseValves(ValveDriver::kHoldSync, now);  // SYNC is back
  for (auto& c : channels_) input(c);
  if (params_->committed()) takeCommitted();
  for (auto& c : channels_) {
    c.loop->count();
    poll(c, now);
    takeCauses(c, now);
  }
  spreadFaults();
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    Channel& c = channels_[i];
    if (c.valve->errorValuePending()) c.valve->pushErrorValue(params_->safeCommand());
    control(c, now);
  }
  master_->poll(now);  // boot work left waiting for the SDO client
  for (auto& c : channels_) {
    c.faults->clearWarnings();
    c.valve->command(c.command());  // each valve written once, into this cycle's TPDO
  }
  const double lat = clock_ ? static_cast<double>(clock_() - now) : 0.0;
  stats_.latency_us.add(lat);
  if (lat > channels_[0].loop->period() * 1e6) ++stats_.overruns;
  for (std::size_t i = 0; i < channels_.size(); ++i) send(channels_[i], static_cast<std::uint8_t>(i), lat);
}

// Period jitter and missed SYNCs.
void ControllerNode::measurePeriod(TimeUs now) noexcept {
  const double Ts = channels_[0].loop->period();
  if (last_sync_ != 0) {
    const double dt = static_cast<double>(now - last_sync_);
    stats_.jitter_us.add(std::fabs(dt - Ts * 1e6));
    if (dt > 1.5 * Ts * 1e6) ++stats_.missed_syncs, ++stats_.overruns;
  }
  last_sync_ = now;
  ++stats_.cycles;
}

// The channel's position of this SYNC, its plausibility, and the loop's activation on the first usable one.
void ControllerNode::input(Channel& c) noexcept {
  c.sample = c.sensor->latch(params_->running());
  c.sensor->checkPlausibility(c.sample, c.loop->command());
  c.loop->activateOn(c.sample.forLoop());
}

// The command: the safe value in a fault, otherwise the controller's (slew-limited after a restart).
void ControllerNode::control(Channel& c, TimeUs now) noexcept {
  const double safe_u = params_->safeCommand();
  const SensorDriver::Sample& s = c.sample;
  const PositionSample p = s.forLoop();
  const auto sp = c.loop->setpointNow();
  if (c.faults->fault() != Fault::None) {
    // Safe state: valve to its safe value every cycle until the causes have been gone long enough
    // (and SYNC, hence the valve, is back); then estimator and integrator restart (no jump).
    c.rec = c.loop->holdSafe(p, sp, safe_u);
    if (c.faults->safeCycle() && s.usable() && (c.valve->holdReasons() & ValveDriver::kHoldSync) == 0)
      recover(c, s.y, now);
    return;
  }
  if (!c.loop->active()) {
    c.rec = c.loop->idle(p, sp, safe_u);
    return;
  }
  c.rec = CycleRecord{};
  if (!c.loop->step(p, sp, safe_u, c.rec)) {
    c.faults->raise(Fault::Estimator);
    takeCauses(c, now);
  }
}

// The setpoint went into this cycle's TPDO, sent right after this callback; the record to the ring.
void ControllerNode::send(Channel& c, std::uint8_t number, double latency_us) noexcept {
  CycleRecord& rec = c.rec;
  c.faults->publish();
  c.loop->publishTime(rec.t);
  if (c.loop->active() && c.loop->running()) {
    rec.u = c.command();
    rec.fault = static_cast<std::uint8_t>(c.faults->fault());
    rec.latency_us = static_cast<float>(latency_us);
    rec.p = c.valve->pressureBar();
    rec.channel = number;
    records_.push(rec);
  }
}

}  // namespace pamc::nodes
