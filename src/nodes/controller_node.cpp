#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "nodes/process_data.hpp"

namespace pamc::nodes {

using canopen::NmtCommand;
using canopen::NmtState;
using canopen::SlaveEvent;
using canopen::TimeUs;

namespace {
constexpr std::uint32_t bit(Fault f) { return faultBit(f); }
constexpr std::uint32_t kWarnMask = warningMask();
constexpr std::uint32_t kSafetyMask = ((1u << kFaultCount) - 2u) & ~kWarnMask;
}  // namespace

// ---- Faults ----------------------------------------------------------------------------------------

void ControllerNode::raise(Fault f, std::uint8_t detail) noexcept {
  pending_ |= bit(f);
  detail_[static_cast<unsigned>(f)] = detail;
}

void ControllerNode::takeCauses(TimeUs now) noexcept {
  const std::uint32_t p = pending_;
  pending_ = 0;
  if (p == 0) return;
  if (reacted_at_us_ == canopen::kNever) reacted_at_us_ = now;
  for (int i = 1; i < kFaultCount; ++i) {
    const auto f = static_cast<Fault>(i);
    if ((p & bit(f)) == 0 || (episode_ & bit(f)) != 0) continue;
    if (f == Fault::BusOff) continue;  // nothing goes out in bus off: its EMCY (0x8140) follows the restart
    episode_ |= bit(f);
    const std::uint8_t m[5] = {static_cast<std::uint8_t>(i), detail_[i], 0, 0, 0};
    node_->emcy().report(emcyCode(f), m);
    if (isWarning(f)) ++fc_.warnings;
  }
  if ((p & kSafetyMask) != 0) {
    if (fault_ == Fault::None) {
      for (int i = 1; i < kFaultCount; ++i)
        if ((p & kSafetyMask & bit(static_cast<Fault>(i))) != 0) {
          fault_ = static_cast<Fault>(i);
          break;
        }
      ++faults_raised_;
      ++fc_.episodes;
      ramp_ = slew_ = false;
      last_u_ = params_->safeCommand();
      valve_cmd_.set(scaling_.commandCounts(last_u_));
      fault_pub_.store(fault_, std::memory_order_relaxed);
    }
    clear_cycles_ = 0;
  }
  if ((p & kWarnMask) != 0) warn_clear_ = 0;
}

void ControllerNode::recover(double y, TimeUs now) noexcept {
  for (int i = 1; i < kFaultCount; ++i) {
    const auto f = static_cast<Fault>(i);
    if ((episode_ & kSafetyMask & bit(f)) != 0) node_->emcy().clear(emcyCode(f));
  }
  episode_ &= kWarnMask;
  if (episode_ == 0) reacted_at_us_ = canopen::kNever;
  fault_ = Fault::None;
  ++fc_.recoveries;
  release(kHoldCollision, now);
  // Estimator and integrator restart from the safe value; the setpoint starts at the position.
  last_u_ = params_->safeCommand();
  ctrl_->activate(last_u_, y);
  startRamp(y);
}

void ControllerNode::onErrorFrame(const canopen::Frame& f) noexcept {
  // Linux error-frame classes (linux/can/error.h): controller problem 0x04 (data[1]: 0x01/0x02 rx/tx
  // overflow, 0x10/0x20 rx/tx error passive), bus off 0x40, restarted after bus off 0x100.
  const bool crtl = (f.id & 0x04u) != 0;
  if ((f.id & 0x40u) != 0) {
    bus_off_ = true;
    raise(Fault::BusOff);
  }
  if ((f.id & 0x100u) != 0 && bus_off_) {
    bus_off_ = false;
    // Back on the bus: now the EMCY can go out.
    const std::uint8_t m[5] = {static_cast<std::uint8_t>(Fault::BusOff), 0, 0, 0, 0};
    node_->emcy().report(emcyCode(Fault::BusOff), m);
    episode_ |= bit(Fault::BusOff);
  }
  if (crtl && (f.data[1] & 0x30u) != 0) raise(Fault::BusError);
  if (crtl && (f.data[1] & 0x03u) != 0) raise(Fault::CanOverrun);
}

void ControllerNode::pushValveErrorValue() noexcept {
  // CiA 401: the valve outputs 0x6444:01 on a communication error; make it the controller's safe value.
  const std::int32_t v = scaling_.commandCounts(params_->safeCommand());
  auto& sdo = node_->sdoClient();
  if (sdo.busy()) return;
  push_valve_ = false;
  if (cfg_.layout.error_value_index == 0) return;
  sdo.downloadValue<std::int32_t>(cfg_.valve_id, cfg_.layout.error_value_index, cfg_.layout.error_value_sub, v, [this](std::uint32_t code, const std::uint8_t*, std::size_t) {
    if (code != canopen::kSdoOk) ++fc_.valve_sdo_errors;
  });
}

void ControllerNode::poll(TimeUs now, bool usable) noexcept {
  const auto& rp = node_->rpdo(1);
  const unsigned missing_limit = params_->running().missing_limit;
  if (active_ && !usable) ++fc_.samples_missing;
  if (usable) ++fc_.positions;
  // The loop never started: say so once no_position_s has passed (the reporter names the COB-ID).
  if (!active_ && operational_at_ != canopen::kNever &&
      static_cast<double>(now - operational_at_) >= cfg_.no_position_s * 1e6)
    raise(Fault::NoPosition, cfg_.sensor_id);
  if (active_ && rp.syncsSinceReception() > missing_limit) raise(Fault::PositionMissing);
  if (rp.conflictInLastCycle()) {
    if (++conflict_run_ >= 3) raise(Fault::SensorConflict, static_cast<std::uint8_t>(rp.cobId() & 0xFF));
  } else {
    conflict_run_ = 0;
  }
  // Polled every cycle (the heartbeat hook fires once per timeout): a fault must not clear while its
  // cause persists.
  const std::uint8_t sensor = cfg_.sensor_id, valve = cfg_.valve_id;
  if (master_->timedOut(sensor)) raise(Fault::SensorHeartbeat, sensor);
  if (active_) {
    if (master_->down(sensor, now)) raise(Fault::SensorState, sensor);
    if (master_->timedOut(valve)) raise(Fault::ValveHeartbeat, valve);
    if (!valveHeld() && master_->configured(valve)) {
      if (master_->down(valve, now)) raise(Fault::ValveState, valve);
      if (cfg_.layout.feedback && !master_->starting(valve, now) && cycle_ > missing_limit &&
          node_->rpdo(2).syncsSinceReception() > missing_limit)
        raise(Fault::ValvePdoMissing);
    }
  }
  // Frames this node could not send (transmit queue full, ENOBUFS beyond the queue): overrun.
  const auto& c = node_->counters();
  if (c.tx_dropped != tx_dropped_seen_) {
    tx_dropped_seen_ = c.tx_dropped;
    raise(Fault::CanOverrun);
  }
  // Frames that missed their deadline, or more than two cycles of frames waiting: this node's frames
  // are not getting onto the bus.
  if (node_->txExpired() != tx_expired_seen_) {
    tx_expired_seen_ = node_->txExpired();
    raise(Fault::CanOverrun);
  }
  if (node_->txBacklog() > 4) raise(Fault::CanOverrun);
  std::uint64_t len = 0;
  for (const auto& p : node_->rpdos()) len += p->wrongLength();
  if (len != pdo_length_seen_) {
    pdo_length_seen_ = len;
    raise(Fault::PdoLength);
  }
  if (node_->sync().wrongLength() != sync_length_seen_) {
    sync_length_seen_ = node_->sync().wrongLength();
    raise(Fault::SyncLength);
  }
  if (bus_off_) raise(Fault::BusOff);
  const ParameterSet& ps = params_->running();
  if (active_ && range_run_ > missing_limit) raise(Fault::PositionRange);
  if (active_ && ps.stuck_span_v > 0.0 && static_cast<double>(same_run_) * Ts_ >= ps.stuck_s &&
      run_u_max_ - run_u_min_ >= ps.stuck_span_v)
    raise(Fault::SensorStuck);
}

// ---- Bumpless return -------------------------------------------------------------------------------

double ControllerNode::runSeconds() const noexcept {
  return run_started_ ? static_cast<double>(cycle_ - preroll_cycles_) * Ts_ : 0.0;
}

void ControllerNode::startRamp(double y) noexcept {
  const double gap = std::fabs(traj_.at(runSeconds()) - y);
  const double seconds = std::clamp(gap / std::max(cfg_.ramp_mm_per_s, 1e-6), 0.05, 5.0);
  ramp_ = true;
  slew_ = true;
  ramp_from_ = y;
  ramp_k0_ = cycle_;
  ramp_cycles_ = std::max<std::uint64_t>(1, static_cast<std::uint64_t>(std::llround(seconds / Ts_)));
}

double ControllerNode::setpoint(double t, int ahead) const noexcept {
  const double target = traj_.at(t);
  if (!ramp_) return target;
  const double s = static_cast<double>(cycle_ + static_cast<std::uint64_t>(ahead) - ramp_k0_) / static_cast<double>(ramp_cycles_);
  return s >= 1.0 ? target : ramp_from_ + (target - ramp_from_) * s;
}

// ---- The cycle -------------------------------------------------------------------------------------

void ControllerNode::onSync(std::uint8_t, TimeUs now) noexcept {
  measurePeriod(now);
  release(kHoldSync, now);  // SYNC is back
  const Sample s = latch();
  checkPlausibility(s);
  advance(s);
  poll(now, s.usable());
  takeCauses(now);
  if (push_valve_) pushValveErrorValue();
  const CycleRecord rec = control(s, now);
  master_->poll(now);  // boot work left waiting for the SDO client
  clearWarnings();
  send(rec, now);
}

// Period jitter and missed SYNCs.
void ControllerNode::measurePeriod(TimeUs now) noexcept {
  if (last_sync_ != 0) {
    const double dt = static_cast<double>(now - last_sync_);
    stats_.jitter_us.add(std::fabs(dt - Ts_ * 1e6));
    if (dt > 1.5 * Ts_ * 1e6) ++stats_.missed_syncs, ++stats_.overruns;
  }
  last_sync_ = now;
  ++stats_.cycles;
}

// The position RPDO of this cycle. A position outside the measuring range (0x2022:01, with 1 % to
// spare at either end: the noise of a muscle resting at an end) is no position: the controller gets
// NaN for it (it holds the last usable one and reports it as not used).
ControllerNode::Sample ControllerNode::latch() const noexcept {
  Sample s;
  s.fresh = node_->rpdo(1).syncsSinceReception() == 0;
  s.raw = position_.get();
  s.y = scaling_.mm(s.raw);
  const double range = params_->running().range_steps, margin = 0.01 * range;
  s.in_range = static_cast<double>(s.raw) >= -margin && static_cast<double>(s.raw) <= range + margin;
  s.y_ctrl = s.in_range ? s.y : std::numeric_limits<double>::quiet_NaN();
  return s;
}

// A run of positions outside the range is a fault (poll); a position that does not change while the
// command moves is a stuck sensor: the run of identical positions and the command's span over it.
void ControllerNode::checkPlausibility(const Sample& s) noexcept {
  if (s.fresh && !s.in_range) {
    ++range_run_;
  } else if (s.fresh) {
    range_run_ = 0;
    if (!have_raw_ || s.raw != raw_last_) {
      have_raw_ = true;
      raw_last_ = s.raw;
      same_run_ = 0;
      run_u_min_ = run_u_max_ = last_u_;
    } else {
      ++same_run_;
    }
  }
  run_u_min_ = std::min(run_u_min_, last_u_);  // the command in effect over the run
  run_u_max_ = std::max(run_u_max_, last_u_);
}

// Activation on the first usable position, a committed parameter set at the cycle boundary, the cycle count.
void ControllerNode::advance(const Sample& s) noexcept {
  if (!active_ && s.usable()) {
    ctrl_->activate(last_u_, s.y);
    active_ = true;
  }
  if (params_->committed()) takeCommitted(s.y_ctrl);
  if (active_) {
    ++cycle_;
    run_started_ = cycle_ > preroll_cycles_;
  }
}

// The command: the safe value in a fault, otherwise the controller's (slew-limited after a restart).
CycleRecord ControllerNode::control(const Sample& s, TimeUs now) noexcept {
  const double safe_u = params_->safeCommand();
  const double t = runSeconds();
  if (ramp_ && cycle_ >= ramp_k0_ + ramp_cycles_) ramp_ = false;
  const double yd = setpoint(t, 0);
  if (fault_ != Fault::None) {
    // Safe state: valve to its safe value every cycle until the causes have been gone long enough
    // (and SYNC, hence the valve, is back); then estimator and integrator restart (no jump).
    last_u_ = safe_u;
    ++fc_.safe_cycles;
    if (++clear_cycles_ >= cfg_.recover_cycles && s.usable() && (master_->holdReasons(cfg_.valve_id) & kHoldSync) == 0)
      recover(s.y, now);
    return CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, s.y, safe_u, 0.0, 0.0, s.y, 0, 0.0f};
  }
  if (!active_) return CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, s.y, safe_u, 0.0, 0.0, s.y, 0, 0.0f};
  const int la = ctrl_->lookahead();
  const double yd_ahead = run_started_ ? setpoint(t + la * Ts_, la) : setpoint(0.0, la);
  const auto o = ctrl_->update(yd, yd_ahead, s.y_ctrl);
  if (!std::isfinite(o.u) || o.estimator_reset) {
    raise(Fault::Estimator);
    takeCauses(now);
    last_u_ = safe_u;
  } else if (slew_) {
    // Bumpless transfer: a restarted estimator may ask for a step (the AMC's model prediction from
    // rest); the valve gets it as a ramp, until the controller's command is within reach.
    const double u = std::clamp(o.u, last_u_ - cfg_.ramp_slew_v, last_u_ + cfg_.ramp_slew_v);
    if (!ramp_ && u == o.u) slew_ = false;
    last_u_ = u;
  } else {
    last_u_ = o.u;
  }
  return CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, s.y, o.u, o.u_n, o.u_c, o.y_hat, 0, 0.0f};
}

// Warnings (wrong-length PDO or SYNC) clear themselves after recover_cycles without a new one.
void ControllerNode::clearWarnings() noexcept {
  if ((episode_ & kWarnMask) == 0 || ++warn_clear_ < cfg_.recover_cycles) return;
  for (int i = 1; i < kFaultCount; ++i) {
    const auto w = static_cast<Fault>(i);
    if (isWarning(w) && (episode_ & bit(w)) != 0) node_->emcy().clear(emcyCode(w));
  }
  episode_ &= ~kWarnMask;
  if (fault_ == Fault::None) reacted_at_us_ = canopen::kNever;
}

// The setpoint goes out in this cycle's TPDO, right after this callback; the record to the ring.
void ControllerNode::send(CycleRecord rec, TimeUs now) noexcept {
  valve_cmd_.set(scaling_.commandCounts(last_u_));
  const double lat = clock_ ? static_cast<double>(clock_() - now) : 0.0;
  stats_.latency_us.add(lat);
  if (lat > Ts_ * 1e6) ++stats_.overruns;
  fault_pub_.store(fault_, std::memory_order_relaxed);
  run_time_pub_.store(rec.t, std::memory_order_relaxed);
  if (active_ && run_started_) {
    rec.u = last_u_;
    rec.fault = static_cast<std::uint8_t>(fault_);
    rec.latency_us = static_cast<float>(lat);
    records_.push(rec);
  }
}

}  // namespace pamc::nodes
