// The controller node's cycle: what the SYNC callback runs, in order, across the drivers, the fault
// supervisor and the control loop. Set-up and hooks are in controller_node_setup.cpp.
#include "nodes/controller_node.hpp"

#include <cmath>

namespace pamc::nodes {

using canopen::TimeUs;

// ---- Faults ----------------------------------------------------------------------------------------

void ControllerNode::takeCauses(TimeUs now) noexcept {
  if (!faults_->takeCauses(now)) return;
  // The safe state begins: the loop's command is the safe value, which send() gives the valve in this
  // cycle's TPDO (the one write of the cycle).
  loop_->enterSafe(params_->safeCommand());
}

void ControllerNode::recover(double y, TimeUs now) noexcept {
  faults_->recover();
  valve_->release(ValveDriver::kHoldCollision, now);
  loop_->recoverFrom(y, params_->safeCommand());
}

// Every fault cause, every cycle: the sensor's and the valve's, then the bus's.
void ControllerNode::poll(TimeUs now, bool usable) noexcept {
  const ParameterSet& ps = params_->running();
  sensor_->supervise(*faults_, now, loop_->active(), usable, ps, loop_->period());
  valve_->supervise(*faults_, now, loop_->active(), loop_->cycle(), ps.missing_limit);
  faults_->pollBus();
}

// ---- The cycle -------------------------------------------------------------------------------------

void ControllerNode::onSync(std::uint8_t, TimeUs now) noexcept {
  measurePeriod(now);
  valve_->release(ValveDriver::kHoldSync, now);  // SYNC is back
  const SensorDriver::Sample s = sensor_->latch(params_->running());
  sensor_->checkPlausibility(s, loop_->command());
  advance(s);
  poll(now, s.usable());
  takeCauses(now);
  if (valve_->errorValuePending()) valve_->pushErrorValue(params_->safeCommand());
  const CycleRecord rec = control(s, now);
  master_->poll(now);  // boot work left waiting for the SDO client
  faults_->clearWarnings();
  send(rec, now);
}

// Period jitter and missed SYNCs.
void ControllerNode::measurePeriod(TimeUs now) noexcept {
  const double Ts = loop_->period();
  if (last_sync_ != 0) {
    const double dt = static_cast<double>(now - last_sync_);
    stats_.jitter_us.add(std::fabs(dt - Ts * 1e6));
    if (dt > 1.5 * Ts * 1e6) ++stats_.missed_syncs, ++stats_.overruns;
  }
  last_sync_ = now;
  ++stats_.cycles;
}

// Activation on the first usable position, a committed parameter set at the cycle boundary, the cycle count.
void ControllerNode::advance(const SensorDriver::Sample& s) noexcept {
  loop_->activateOn(s.forLoop());
  if (params_->committed()) takeCommitted(s.y_ctrl);
  loop_->count();
}

// The command: the safe value in a fault, otherwise the controller's (slew-limited after a restart).
CycleRecord ControllerNode::control(const SensorDriver::Sample& s, TimeUs now) noexcept {
  const double safe_u = params_->safeCommand();
  const PositionSample p = s.forLoop();
  const auto sp = loop_->setpointNow();
  if (faults_->fault() != Fault::None) {
    // Safe state: valve to its safe value every cycle until the causes have been gone long enough
    // (and SYNC, hence the valve, is back); then estimator and integrator restart (no jump).
    const CycleRecord rec = loop_->holdSafe(p, sp, safe_u);
    if (faults_->safeCycle() && s.usable() && (valve_->holdReasons() & ValveDriver::kHoldSync) == 0) recover(s.y, now);
    return rec;
  }
  if (!loop_->active()) return loop_->idle(p, sp, safe_u);
  CycleRecord rec;
  if (!loop_->step(p, sp, safe_u, rec)) {
    faults_->raise(Fault::Estimator);
    takeCauses(now);
  }
  return rec;
}

// The setpoint goes out in this cycle's TPDO, right after this callback; the record to the ring.
void ControllerNode::send(CycleRecord rec, TimeUs now) noexcept {
  valve_->command(loop_->command());
  const double lat = clock_ ? static_cast<double>(clock_() - now) : 0.0;
  stats_.latency_us.add(lat);
  if (lat > loop_->period() * 1e6) ++stats_.overruns;
  faults_->publish();
  loop_->publishTime(rec.t);
  if (loop_->active() && loop_->running()) {
    rec.u = loop_->command();
    rec.fault = static_cast<std::uint8_t>(faults_->fault());
    rec.latency_us = static_cast<float>(lat);
    rec.p = valve_->pressureBar();
    records_.push(rec);
  }
}

}  // namespace pamc::nodes
