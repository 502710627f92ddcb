#include "nodes/sensor_driver.hpp"

#include <algorithm>
#include <limits>
#include <string>

namespace pamc::nodes {

using canopen::TimeUs;

SensorDriver::SensorDriver(canopen::Node& node, canopen::NmtMaster& master, std::uint8_t id, const pd::Scaling& scaling,
                           double no_position_s, unsigned rpdo, std::uint16_t object)
    : node_(node),
      master_(master),
      id_(id),
      rpdo_(rpdo),
      object_(object),
      scaling_(scaling),
      no_position_s_(no_position_s) {
  master_.addSlave(id_);
}

void SensorDriver::readStepAtBoot() {
  // CiA 406: 0x6005:01 is the measuring step in nm; the loop sees it before the sensor starts.
  master_.addReads(
      id_, {canopen::SlaveBoot::Read{0x6005, 1, [this](const std::uint8_t* d, std::size_t len, std::string* why) {
                                       std::uint32_t nm = 0;
                                       for (std::size_t i = 0; i < len && i < 4; ++i)
                                         nm |= static_cast<std::uint32_t>(d[i]) << (8 * i);
                                       if (len != 4 || nm == 0) {
                                         *why = "measuring step " + std::to_string(nm) + " nm (" + std::to_string(len) +
                                                " bytes) is not a step";
                                         return false;
                                       }
                                       scaling_.position_step_mm = nm * 1e-6;
                                       return true;
                                     }}});
}

void SensorDriver::onOperational(TimeUs now) noexcept {
  operational_at_ = now;
  cob_pub_.store(pdo_->cobId() & 0x7FFu, std::memory_order_relaxed);
}

void SensorDriver::onEvent(canopen::SlaveEvent ev, TimeUs now, FaultSupervisor& f, bool active) noexcept {
  using canopen::SlaveEvent;
  switch (ev) {
    case SlaveEvent::Configured:
    case SlaveEvent::KeptAlive: onBooted(now); break;
    case SlaveEvent::BootFailed: f.raise(Fault::SlaveBoot, id_); break;
    case SlaveEvent::Lost: f.raise(Fault::SensorHeartbeat, id_); break;
    case SlaveEvent::BootUp:
    case SlaveEvent::LeftOperational:
    case SlaveEvent::Stopped:
      if (active) f.raise(Fault::SensorState, id_);
      break;
  }
}

// The position RPDO of this cycle. A position outside the measuring range (0x2022:01, with 1 % to
// spare at either end: the noise of a muscle resting at an end) is no position: the controller gets
// NaN for it (it holds the last usable one and reports it as not used).
SensorDriver::Sample SensorDriver::latch(const ParameterSet& ps) const noexcept {
  Sample s;
  s.fresh = pdo_->syncsSinceReception() == 0;
  s.raw = position_.get();
  s.y = scaling_.mm(s.raw);
  const double range = ps.range_steps, margin = 0.01 * range;
  s.in_range = static_cast<double>(s.raw) >= -margin && static_cast<double>(s.raw) <= range + margin;
  s.y_ctrl = s.in_range ? s.y : std::numeric_limits<double>::quiet_NaN();
  return s;
}

// A run of positions outside the range is a fault (supervise); a position that does not change while
// the command moves is a stuck sensor: the run of identical positions and the command's span over it.
void SensorDriver::checkPlausibility(const Sample& s, double u) noexcept {
  if (s.fresh && !s.in_range) {
    ++range_run_;
  } else if (s.fresh) {
    range_run_ = 0;
    if (!have_raw_ || s.raw != raw_last_) {
      have_raw_ = true;
      raw_last_ = s.raw;
      same_run_ = 0;
      run_u_min_ = run_u_max_ = u;
    } else {
      ++same_run_;
    }
  }
  run_u_min_ = std::min(run_u_min_, u);  // the command in effect over the run
  run_u_max_ = std::max(run_u_max_, u);
}

void SensorDriver::supervise(FaultSupervisor& f, const DriverCycle& c) noexcept {
  const canopen::Rpdo& rp = *pdo_;
  const ParameterSet& ps = *c.ps;
  const TimeUs now = c.now;
  const bool active = c.active, usable = c.usable;
  const double Ts = c.Ts;
  const unsigned limit = ps.missing_limit;
  if (active && !usable) ++samples_missing_;
  if (usable) ++positions_;
  // The loop never started: say so once no_position_s has passed (the reporter names the COB-ID).
  if (!active && operational_at_ != canopen::kNever && !master_.booting(id_) &&
      static_cast<double>(now - operational_at_) >= no_position_s_ * 1e6)
    f.raise(Fault::NoPosition, id_);
  if (active && rp.syncsSinceReception() > limit) f.raise(Fault::PositionMissing);
  if (rp.conflictInLastCycle()) {
    if (++conflict_run_ >= 3) f.raise(Fault::SensorConflict, static_cast<std::uint8_t>(rp.cobId() & 0xFF));
  } else {
    conflict_run_ = 0;
  }
  // Polled every cycle (the heartbeat hook fires once per timeout): a fault must not clear while its
  // cause persists.
  if (master_.timedOut(id_)) f.raise(Fault::SensorHeartbeat, id_);
  if (active && master_.down(id_, now)) f.raise(Fault::SensorState, id_);
  if (active && range_run_ > limit) f.raise(Fault::PositionRange);
  if (active && ps.stuck_span_v > 0.0 && static_cast<double>(same_run_) * Ts >= ps.stuck_s &&
      run_u_max_ - run_u_min_ >= ps.stuck_span_v)
    f.raise(Fault::SensorStuck);
}

}  // namespace pamc::nodes
