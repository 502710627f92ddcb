#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pamc::nodes {

using canopen::HeartbeatEvent;
using canopen::NmtCommand;
using canopen::NmtState;
using canopen::TimeUs;

const char* toString(Fault f) {
  switch (f) {
    case Fault::None: return "none";
    case Fault::SensorHeartbeat: return "sensor heartbeat lost";
    case Fault::PositionMissing: return "position PDO missing";
    case Fault::Estimator: return "estimator failure (non-finite or reset)";
    case Fault::BusError: return "CAN bus error";
    case Fault::ValveHeartbeat: return "valve heartbeat lost";
  }
  return "?";
}

// CiA 301 emergency error codes.
std::uint16_t emcyCode(Fault f) {
  switch (f) {
    case Fault::None: return 0x0000;
    case Fault::SensorHeartbeat: return 0x8130;  // life guard / heartbeat error
    case Fault::PositionMissing: return 0x8250;  // RPDO timeout
    case Fault::Estimator: return 0x6100;        // internal software
    case Fault::BusError: return 0x8120;         // CAN in error passive mode (or bus off)
    case Fault::ValveHeartbeat: return 0x8130;
  }
  return 0xFF00;
}

namespace {
// The parameters in 0x2000 (gains) and 0x2001 (model) by sub-index 1..n, read and written alike.
constexpr double control::ControllerConfig::*kGains[] = {
    &control::ControllerConfig::kp,    &control::ControllerConfig::ki,    &control::ControllerConfig::kc,
    &control::ControllerConfig::beta1, &control::ControllerConfig::beta2, &control::ControllerConfig::beta3,
    &control::ControllerConfig::delta, &control::ControllerConfig::b0};
constexpr double model::BoucWenParams::*kModel[] = {&model::BoucWenParams::k,     &model::BoucWenParams::rho,
                                                    &model::BoucWenParams::b,     &model::BoucWenParams::alpha,
                                                    &model::BoucWenParams::beta,  &model::BoucWenParams::gamma};

// Trajectory choice 0x2011 and its parameters 0x2012: frequency, low, high, offset, amplitude,
// amplitude at end, duration.
sim::Trajectory trajectoryFromOd(canopen::ObjectDictionary& od) {
  const int choice = od.ref<std::uint8_t>(0x2011, 0).get();
  auto p = [&](std::uint8_t sub) { return od.ref<double>(0x2012, sub).get(); };
  switch (choice) {
    case 0: return sim::Trajectory::constant(p(4));
    case 1: return sim::Trajectory::triangle(p(1), p(2), p(3));
    case 2: return sim::Trajectory::sine(p(1), p(5), p(4));
    case 3: return sim::Trajectory::sineDescending(p(1), p(4), p(5), p(6), p(7));
    case 4: return sim::Trajectory::square(p(1), p(2), p(3));
    case 5: return sim::Trajectory::sawtooth(p(1), p(2), p(3));
  }
  throw std::invalid_argument("0x2011 trajectory choice " + std::to_string(choice) + " is not 0..5");
}

// False when the shape has no representation in 0x2011/0x2012 (it then runs from the command line).
bool trajectoryToOd(canopen::ObjectDictionary& od, const sim::Trajectory& t) {
  using S = sim::Trajectory::Shape;
  int choice = 0;
  switch (t.shape) {
    case S::Constant: choice = 0; break;
    case S::Triangle: choice = 1; break;
    case S::Sine: choice = 2; break;
    case S::SineDescending: choice = 3; break;
    case S::Square: choice = 4; break;
    case S::Sawtooth: choice = 5; break;
    default: return false;
  }
  od.ref<std::uint8_t>(0x2011, 0).set(static_cast<std::uint8_t>(choice));
  od.ref<double>(0x2012, 1).set(t.freq_hz);
  od.ref<double>(0x2012, 2).set(t.lo);
  od.ref<double>(0x2012, 3).set(t.hi);
  od.ref<double>(0x2012, 4).set(t.offset);
  od.ref<double>(0x2012, 5).set(t.amplitude);
  od.ref<double>(0x2012, 6).set(t.amplitude_end);
  od.ref<double>(0x2012, 7).set(t.duration);
  return true;
}
}  // namespace

ControllerNode::ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                               std::function<TimeUs()> clock)
    : cfg_(cfg), clock_(std::move(clock)) {
  node_ = canopen::Node::fromEds(cfg.eds_path, transport);
  applyOverrides();
  auto& od = node_->od();
  position_ = od.ref<std::int32_t>(0x3000, 0);
  valve_cmd_ = od.ref<std::int16_t>(0x3002, 0);
  configureFromOd();

  node_->onSync([this](std::uint8_t counter, TimeUs now) { onSync(counter, now); });
  node_->onHeartbeat([this](std::uint8_t id, HeartbeatEvent ev, NmtState, TimeUs) {
    if (ev == HeartbeatEvent::Timeout) raise(id == cfg_.sensor_id ? Fault::SensorHeartbeat : Fault::ValveHeartbeat);
    // A slave that rebooted waits in Pre-operational: start it again.
    if (ev == HeartbeatEvent::BootUp) node_->sendNmt(NmtCommand::Start, id);
  });
  node_->onErrorFrame([this](const canopen::Frame& f, TimeUs) {
    // Linux error-frame classes (linux/can/error.h): bus off (0x40), or a controller problem (0x04)
    // reporting error passive (data[1] 0x10 rx / 0x20 tx). Other classes are counted by the layer.
    const bool bus_off = (f.id & 0x40u) != 0;
    const bool passive = (f.id & 0x04u) != 0 && (f.data[1] & 0x30u) != 0;
    if (bus_off || passive) raise(Fault::BusError);
  });
  node_->onStateChange([this](NmtState, NmtState to, TimeUs) {
    if (to != NmtState::Operational) return;
    // Parameters set over SDO take effect here; a set that does not configure keeps the running
    // controller and raises a fault instead of escaping into the event loop.
    try {
      configureFromOd();
    } catch (const std::exception&) {
      ++config_errors_;
      raise(Fault::Estimator);
    }
  });
  // A reset restores the EDS defaults: put the command line's choices back.
  node_->onReset([this](NmtCommand, TimeUs) { applyOverrides(); });
}

void ControllerNode::applyOverrides() {
  auto& od = node_->od();
  // Command-line choices go into the dictionary, so SDO reads show what runs.
  const auto& cfg = cfg_;
  if (cfg.kind >= 0) od.ref<std::uint8_t>(0x2010, 0).set(static_cast<std::uint8_t>(cfg.kind));
  if (cfg.gains_from_config)
    for (std::uint8_t i = 0; i < 8; ++i) od.ref<double>(0x2000, static_cast<std::uint8_t>(i + 1)).set(cfg.ctrl.*kGains[i]);
  for (std::uint8_t i = 0; i < 6; ++i)
    od.ref<double>(0x2001, static_cast<std::uint8_t>(i + 1)).set(cfg.ctrl.model.core().*kModel[i]);
  if (cfg.has_trajectory) traj_override_ = !trajectoryToOd(od, cfg.trajectory);
  if (cfg.period_us) od.ref<std::uint32_t>(0x1006, 0).set(cfg.period_us);
  if (!cfg.produce_sync) {
    auto cob = od.ref<std::uint32_t>(0x1005, 0);
    cob.set(cob.get() & ~0x40000000u);  // consume SYNC from another master
  }
}

void ControllerNode::configureFromOd() {
  auto& od = node_->od();
  control::ControllerConfig c = cfg_.ctrl;
  for (std::uint8_t i = 0; i < 8; ++i) c.*kGains[i] = od.ref<double>(0x2000, static_cast<std::uint8_t>(i + 1)).get();
  for (std::uint8_t i = 0; i < 6; ++i)
    c.model.core().*kModel[i] = od.ref<double>(0x2001, static_cast<std::uint8_t>(i + 1)).get();
  c.ukf.P0_h = od.ref<double>(0x2002, 1).get();
  c.ukf.P0_f = od.ref<double>(0x2002, 2).get();
  c.ukf.Q_h = od.ref<double>(0x2002, 3).get();
  c.ukf.Q_f = od.ref<double>(0x2002, 4).get();
  c.ukf.R = od.ref<double>(0x2002, 5).get();
  const std::uint32_t period_us = od.ref<std::uint32_t>(0x1006, 0).get();
  if (period_us == 0) throw std::invalid_argument(cfg_.eds_path + ": 0x1006 communication cycle period is 0");
  // Build everything first, then swap: a failure leaves the running controller in place.
  Ts_ = period_us * 1e-6;
  c.Ts = Ts_;
  c.delay_cycles = 2;  // see controller_node.hpp: y_k reflects u_{k-3}
  kind_ = static_cast<control::Kind>(od.ref<std::uint8_t>(0x2010, 0).get());
  traj_ = trajectoryFromOd(od);
  if (traj_override_) traj_ = cfg_.trajectory;  // shapes the OD cannot hold
  safe_u_ = std::clamp(od.ref<double>(0x2020, 0).get(), 0.0, 10.0) - 5.0;
  missing_limit_ = od.ref<std::uint8_t>(0x2021, 0).get();
  auto fresh_ctrl = control::makeController(kind_, c);
  ctrl_ = std::move(fresh_ctrl);
  cfg_.ctrl.Ts = c.Ts;
  active_ = false;
  run_started_ = false;
  cycle_ = 0;
  preroll_cycles_ = static_cast<std::uint64_t>(std::llround(cfg_.preroll_s / Ts_));
  last_u_ = safe_u_;
  valve_cmd_.set(0);
  run_time_pub_.store(0.0, std::memory_order_relaxed);
}

void ControllerNode::start(TimeUs now) {
  node_->start(now);
  node_->applyNmt(NmtCommand::Start);
  node_->sendNmt(NmtCommand::Start, cfg_.sensor_id);
  node_->sendNmt(NmtCommand::Start, cfg_.valve_id);
}

void ControllerNode::raise(Fault f) noexcept {
  if (pending_ == Fault::None) pending_ = f;
}

static std::int16_t toValve(double u) noexcept {
  const double v = std::clamp(u + 5.0, 0.0, 10.0);  // valve volts
  return static_cast<std::int16_t>(std::lround(v * 32767.0 / 10.0));
}

void ControllerNode::onSync(std::uint8_t, TimeUs now) noexcept {
  // Period jitter and missed SYNCs.
  if (last_sync_ != 0) {
    const double dt = static_cast<double>(now - last_sync_);
    stats_.jitter_us.add(std::fabs(dt - Ts_ * 1e6));
    if (dt > 1.5 * Ts_ * 1e6) ++stats_.missed_syncs, ++stats_.overruns;
  }
  last_sync_ = now;
  ++stats_.cycles;

  // Latch: the position RPDO of this cycle, or a fault if it has been missing too long.
  const auto& rp = node_->rpdo(1);
  const bool fresh = rp.syncsSinceReception() == 0;  // a position arrived in the last cycle
  if (!active_ && fresh) {
    ctrl_->activate(last_u_, position_.get() * 1e-3);
    active_ = true;
  }
  if (active_ && rp.syncsSinceReception() > missing_limit_) raise(Fault::PositionMissing);
  // Polled every cycle (the heartbeat hook fires once per timeout): a fault must not clear while
  // its cause persists.
  const auto& hb = node_->heartbeatConsumer();
  if (hb.timedOut(cfg_.sensor_id)) raise(Fault::SensorHeartbeat);
  if (active_ && (hb.timedOut(cfg_.valve_id) || hb.remoteState(cfg_.valve_id) == NmtState::Stopped))
    raise(Fault::ValveHeartbeat);

  CycleRecord rec;
  const double y = position_.get() * 1e-3;
  if (active_) {
    ++cycle_;
    run_started_ = cycle_ > preroll_cycles_;
  }
  const double t = run_started_ ? static_cast<double>(cycle_ - preroll_cycles_) * Ts_ : 0.0;
  const double yd = traj_.at(t);
  rec = CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, y, safe_u_, 0.0, 0.0, y, 0, 0.0f};
  if (pending_ != Fault::None) {
    if (fault_ == Fault::None) {
      fault_ = pending_;
      ++faults_raised_;
      node_->emcy().report(emcyCode(fault_));
    }
    pending_ = Fault::None;
    clear_cycles_ = 0;
  }
  if (fault_ != Fault::None) {
    // Safe state: valve to its safe value every cycle until the fault has been gone long enough;
    // then estimator and integrator restart from the present command and position (no jump).
    last_u_ = safe_u_;
    if (++clear_cycles_ >= cfg_.recover_cycles && fresh) {
      node_->emcy().clear(emcyCode(fault_));
      fault_ = Fault::None;
      ctrl_->activate(last_u_, y);
    }
  } else if (active_) {
    const double yd_ahead = run_started_ ? traj_.at(t + ctrl_->lookahead() * Ts_) : traj_.at(0.0);
    const auto o = ctrl_->update(yd, yd_ahead, y);
    if (!std::isfinite(o.u) || o.estimator_reset) {
      raise(Fault::Estimator);
      last_u_ = safe_u_;
    } else {
      last_u_ = o.u;
    }
    rec = CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, y, o.u, o.u_n, o.u_c, o.y_hat, 0, 0.0f};
  }
  // Send: the setpoint goes out in this cycle's TPDO, right after this callback.
  valve_cmd_.set(toValve(last_u_));
  const double lat = clock_ ? static_cast<double>(clock_() - now) : 0.0;
  stats_.latency_us.add(lat);
  if (lat > Ts_ * 1e6) ++stats_.overruns;
  fault_pub_.store(fault_, std::memory_order_relaxed);
  run_time_pub_.store(t, std::memory_order_relaxed);
  if (active_ && run_started_) {
    rec.u = last_u_;
    rec.fault = static_cast<std::uint8_t>(fault_);
    rec.latency_us = static_cast<float>(lat);
    records_.push(rec);
  }
}

}  // namespace pamc::nodes
