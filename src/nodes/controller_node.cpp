#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <iterator>
#include <limits>
#include <stdexcept>

#include "model/bouc_wen.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

using canopen::Entry;
using canopen::HeartbeatEvent;
using canopen::NmtCommand;
using canopen::NmtState;
using canopen::TimeUs;

namespace {
constexpr std::uint32_t bit(Fault f) { return faultBit(f); }
constexpr std::uint32_t kWarnMask = warningMask();
constexpr std::uint32_t kSafetyMask = ((1u << kFaultCount) - 2u) & ~kWarnMask;
constexpr TimeUs kStartGraceUs = 300'000;  // a started slave must report Operational within 3 heartbeats

// The parameters in 0x2000 (gains) and 0x2001 (model) by sub-index 1..n, read and written alike.
constexpr double control::ControllerConfig::*kGains[] = {
    &control::ControllerConfig::kp,    &control::ControllerConfig::ki,    &control::ControllerConfig::kc,
    &control::ControllerConfig::beta1, &control::ControllerConfig::beta2, &control::ControllerConfig::beta3,
    &control::ControllerConfig::delta, &control::ControllerConfig::b0};
constexpr double model::BoucWenParams::*kModel[] = {&model::BoucWenParams::k,     &model::BoucWenParams::rho,
                                                    &model::BoucWenParams::b,     &model::BoucWenParams::alpha,
                                                    &model::BoucWenParams::beta,  &model::BoucWenParams::gamma};
constexpr double estimation::ActiveModelSettings::*kUkf[] = {
    &estimation::ActiveModelSettings::P0_h, &estimation::ActiveModelSettings::P0_f,
    &estimation::ActiveModelSettings::Q_h, &estimation::ActiveModelSettings::Q_f, &estimation::ActiveModelSettings::R,
    &estimation::ActiveModelSettings::Q_h_lag, &estimation::ActiveModelSettings::Q_f_lag,
    &estimation::ActiveModelSettings::Q_out, &estimation::ActiveModelSettings::diverge};
constexpr std::uint8_t kUkfSubs = static_cast<std::uint8_t>(std::size(kUkf));

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

// Ranges the controller accepts beyond the EDS limits: kp and kc up to 10 V/mm (the valve's whole
// range for 1 mm of error), ki up to 100 V/(mm s); the divisors ESO delta, ESO b0 and UKF R above 0.
std::uint32_t applicationRange(std::uint16_t idx, std::uint8_t sub, double v) {
  if (((idx == 0x2000 && (sub == 7 || sub == 8)) || (idx == 0x2002 && sub == 5)) && !(v > 0.0))
    return canopen::kAbortValueTooLow;
  return canopen::kSdoOk;
}

std::int16_t toValve(double u) noexcept { return pd::commandToCounts(u); }

}  // namespace

ControllerNode::ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                               std::function<TimeUs()> clock)
    : cfg_(cfg), clock_(std::move(clock)) {
  node_ = canopen::Node::fromEds(cfg.eds_path, transport);
  sensor_.id = cfg.sensor_id;
  valve_.id = cfg.valve_id;
  running_.ctrl = cfg_.ctrl;
  applyOverrides();
  auto& od = node_->od();
  position_ = od.ref<std::int32_t>(0x3000, 0);
  valve_cmd_ = od.ref<std::int16_t>(0x3002, 0);
  staged_flag_ = od.ref<std::uint8_t>(0x2003, 2);
  sets_applied_ = od.ref<std::uint8_t>(0x2003, 3);
  configureFromOd();
  installGuards();

  node_->onSync([this](std::uint8_t counter, TimeUs now) { onSync(counter, now); });
  node_->onHeartbeat([this](std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) {
    onHeartbeatEvent(id, ev, st, now);
  });
  node_->onErrorFrame([this](const canopen::Frame& f, TimeUs) { onErrorFrame(f); });
  // SYNC consumer: without SYNC no cycle runs, so act in the hook: safe value, EMCY, and the valve to
  // Pre-operational, where it outputs its error value (it would hold the last command otherwise).
  node_->onSyncTimeout([this](TimeUs now) {
    raise(Fault::SyncLost);
    takeCauses(now);
    hold(kHoldSync);
  });
  node_->onCollision([this](const canopen::Frame& f, TimeUs now) {
    ++fc_.collisions;
    fc_.last_collision_cob = f.id;
    collision_pub_.store(f.id, std::memory_order_relaxed);
    raise(Fault::IdCollision, static_cast<std::uint8_t>(f.id & 0xFF));
    takeCauses(now);
    // The other node may command the valve too: keep it in Pre-operational until the collision is gone.
    hold(kHoldCollision);
  });
  node_->onStateChange([this](NmtState from, NmtState to, TimeUs now) {
    if (to == NmtState::Operational) {
      // Parameters set over SDO take effect here; a set that does not configure keeps the running
      // controller and raises a fault instead of escaping into the event loop.
      try {
        configureFromOd();
      } catch (const std::exception&) {
        ++config_errors_;
        ++fc_.sets_refused;
        raise(Fault::Estimator);
      }
      startSlave(sensor_, now);
      if ((hold_ & kHoldSelf) != 0) release(kHoldSelf, now);  // starts the valve once nothing else holds it
      else if (hold_ == 0) startSlave(valve_, now);
      push_valve_ = true;
      pushValveErrorValue();
    } else if (from == NmtState::Operational) {
      // No more setpoints from here: the valve goes to its error value instead of holding the last one.
      // The loop stops (PDOs do not move outside Operational); NMT start configures it afresh.
      hold(kHoldSelf);
      active_ = run_started_ = false;
      ramp_ = slew_ = false;
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
  if (cfg.period_us) {
    od.ref<std::uint32_t>(0x1006, 0).set(cfg.period_us);
    // The synchronous window keeps its share of the period (0x1007 default: 800 of 1000 us).
    if (auto* w = od.find(0x1007, 0)) w->set<std::uint32_t>(cfg.period_us / 5 * 4);
  }
  if (!cfg.produce_sync) {
    auto cob = od.ref<std::uint32_t>(0x1005, 0);
    cob.set(cob.get() & ~0x40000000u);  // consume SYNC from another master
  }
}

void ControllerNode::installGuards() {
  using canopen::kAbortDeviceState;
  using canopen::kAbortValueRange;
  using canopen::kAbortValueTooLow;
  using canopen::kSdoOk;
  auto& od = node_->od();
  // What the loop is wired to cannot change under it: the controller choice, the trajectory, the
  // process data, and the communication objects of the cycle are refused while Operational.
  auto while_running = [this](const Entry&, const std::uint8_t*, std::size_t) -> std::uint32_t {
    return node_->nmtState() == NmtState::Operational ? kAbortDeviceState : kSdoOk;
  };
  for (std::uint16_t idx : {0x1005, 0x1006, 0x1007, 0x1016, 0x1400, 0x1401, 0x1600, 0x1601, 0x1800, 0x1A00, 0x2010,
                            0x2011, 0x2012, 0x3000, 0x3001, 0x3002}) {
    if (od.hasObject(idx)) od.addValidator(idx, while_running);
  }
  // Numbers: finite (the EDS limits are checked before the validators run).
  auto finite = [](const Entry& e, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
    if (e.dataType() != canopen::DataType::Real64 || len != 8) return kSdoOk;
    double v;
    std::memcpy(&v, d, 8);
    return std::isfinite(v) ? kSdoOk : kAbortValueRange;
  };
  for (std::uint16_t idx : {0x2000, 0x2001, 0x2002, 0x2012, 0x2020, 0x2022}) od.addValidator(idx, finite);
  // The application's ranges, narrower than the EDS limits (which are those of the data type).
  for (std::uint8_t sub = 1; sub <= 8; ++sub) {
    od.validate<double>(0x2000, sub, [sub](double v) { return applicationRange(0x2000, sub, v); });
  }
  od.validate<double>(0x2002, 5, [](double v) { return applicationRange(0x2002, 5, v); });
  // A parameter written while the loop runs is staged: the dictionary shows it, the loop does not use it.
  auto staged = [this](Entry&) { staged_flag_.set(1); };
  for (std::uint16_t idx : {0x2000, 0x2001, 0x2002, 0x2020, 0x2021, 0x2022}) od.addObserver(idx, staged);
  // 0x2003:01: 1 commits the staged set (checked here, taken at the next SYNC), 0 discards it.
  od.addValidator(0x2003, 1, [this](const Entry&, const std::uint8_t* d, std::size_t len) -> std::uint32_t {
    if (len != 1) return kSdoOk;
    if (d[0] == 1) return commit();
    discard();
    return kSdoOk;
  });
  od.addObserver(0x2003, 1, [](Entry& e) { e.set<std::uint8_t>(0); });
}

ControllerNode::Params ControllerNode::readParams() {
  auto& od = node_->od();
  Params p;
  p.ctrl = running_.ctrl;
  for (std::uint8_t i = 0; i < 8; ++i) p.ctrl.*kGains[i] = od.ref<double>(0x2000, static_cast<std::uint8_t>(i + 1)).get();
  for (std::uint8_t i = 0; i < 6; ++i)
    p.ctrl.model.core().*kModel[i] = od.ref<double>(0x2001, static_cast<std::uint8_t>(i + 1)).get();
  for (std::uint8_t i = 0; i < kUkfSubs; ++i) p.ctrl.ukf.*kUkf[i] = od.ref<double>(0x2002, static_cast<std::uint8_t>(i + 1)).get();
  p.safe_u = pd::commandFromVolts(od.ref<double>(0x2020, 0).get());
  p.missing_limit = od.ref<std::uint8_t>(0x2021, 0).get();
  for (std::uint8_t i = 0; i < 3; ++i) p.*kPlausibility[i] = od.ref<double>(0x2022, static_cast<std::uint8_t>(i + 1)).get();
  return p;
}

void ControllerNode::writeParams(const Params& p) {
  auto& od = node_->od();
  for (std::uint8_t i = 0; i < 8; ++i) od.ref<double>(0x2000, static_cast<std::uint8_t>(i + 1)).set(p.ctrl.*kGains[i]);
  for (std::uint8_t i = 0; i < 6; ++i)
    od.ref<double>(0x2001, static_cast<std::uint8_t>(i + 1)).set(p.ctrl.model.core().*kModel[i]);
  for (std::uint8_t i = 0; i < kUkfSubs; ++i) od.ref<double>(0x2002, static_cast<std::uint8_t>(i + 1)).set(p.ctrl.ukf.*kUkf[i]);
  od.ref<double>(0x2020, 0).set(pd::valveVolts(p.safe_u));
  od.ref<std::uint8_t>(0x2021, 0).set(static_cast<std::uint8_t>(p.missing_limit));
  for (std::uint8_t i = 0; i < 3; ++i) od.ref<double>(0x2022, static_cast<std::uint8_t>(i + 1)).set(p.*kPlausibility[i]);
}

std::uint32_t ControllerNode::checkParams(const Params& p, std::string* why) {
  using canopen::kSdoOk;
  auto& od = node_->od();
  // Every value against the rules an SDO write would meet (values set locally skip those).
  auto check = [&](std::uint16_t idx, std::uint8_t sub, double v) -> std::uint32_t {
    const Entry& e = od.entry(idx, sub);
    std::uint32_t code = std::isfinite(v) ? kSdoOk : canopen::kAbortValueRange;
    if (code == kSdoOk) code = od.checkValue(e, reinterpret_cast<const std::uint8_t*>(&v), sizeof v);
    if (code == kSdoOk) code = applicationRange(idx, sub, v);
    if (code != kSdoOk && why) {
      char b[160];
      std::snprintf(b, sizeof b, "%s %s = %g: %s", canopen::entryName(idx, sub).c_str(), e.name().c_str(), v,
                    canopen::sdoAbortText(code));
      *why = b;
    }
    return code;
  };
  for (std::uint8_t i = 0; i < 8; ++i)
    if (auto c = check(0x2000, static_cast<std::uint8_t>(i + 1), p.ctrl.*kGains[i])) return c;
  for (std::uint8_t i = 0; i < 6; ++i)
    if (auto c = check(0x2001, static_cast<std::uint8_t>(i + 1), p.ctrl.model.core().*kModel[i])) return c;
  for (std::uint8_t i = 0; i < kUkfSubs; ++i)
    if (auto c = check(0x2002, static_cast<std::uint8_t>(i + 1), p.ctrl.ukf.*kUkf[i])) return c;
  if (auto c = check(0x2020, 0, pd::valveVolts(p.safe_u))) return c;
  for (std::uint8_t i = 0; i < 3; ++i)
    if (auto c = check(0x2022, static_cast<std::uint8_t>(i + 1), p.*kPlausibility[i])) return c;
  // Each value may be fine alone and the set still unusable: CiA 301 "general parameter incompatibility".
  if (!model::boucWenStable(p.ctrl.model.core(), pd::kCommandMin, pd::kCommandMax, why)) return canopen::kAbortParameterIncompatible;
  return kSdoOk;
}

void ControllerNode::configureFromOd() {
  auto& od = node_->od();
  Params p = readParams();
  std::string why;
  if (checkParams(p, &why) != canopen::kSdoOk) throw std::invalid_argument(cfg_.eds_path + ": parameter set refused: " + why);
  const std::uint32_t period_us = od.ref<std::uint32_t>(0x1006, 0).get();
  if (period_us == 0) throw std::invalid_argument(cfg_.eds_path + ": 0x1006 communication cycle period is 0");
  // Build everything first, then swap: a failure leaves the running controller in place.
  const double Ts = period_us * 1e-6;
  p.ctrl.Ts = Ts;
  p.ctrl.delay_cycles = cfg_.delay_cycles;  // 2 on this rig: y_k reflects u_{k-3} (controller_node.hpp)
  const auto kind = static_cast<control::Kind>(od.ref<std::uint8_t>(0x2010, 0).get());
  auto traj = trajectoryFromOd(od);
  if (traj_override_) traj = cfg_.trajectory;  // shapes the OD cannot hold
  auto fresh_ctrl = control::makeController(kind, p.ctrl);
  Ts_ = Ts;
  kind_ = kind;
  traj_ = traj;
  ctrl_ = std::move(fresh_ctrl);
  running_ = std::move(p);
  safe_u_ = std::clamp(running_.safe_u, pd::kCommandMin, pd::kCommandMax);
  missing_limit_ = running_.missing_limit;
  cfg_.ctrl.Ts = Ts;
  next_ctrl_.reset();
  commit_ready_ = false;
  staged_flag_.set(0);
  ++fc_.sets_applied;
  sets_applied_.set(static_cast<std::uint8_t>(fc_.sets_applied));
  active_ = false;
  run_started_ = false;
  ramp_ = false;
  cycle_ = 0;
  preroll_cycles_ = static_cast<std::uint64_t>(std::llround(cfg_.preroll_s / Ts_));
  last_u_ = safe_u_;
  valve_cmd_.set(0);
  run_time_pub_.store(0.0, std::memory_order_relaxed);
}

std::uint32_t ControllerNode::commit() {
  // Runs in the SDO server (between cycles, never inside one): check, build, hand over.
  Params p = readParams();
  std::string why;
  std::uint32_t code = checkParams(p, &why);
  std::unique_ptr<control::Controller> c;
  if (code == canopen::kSdoOk) {
    try {
      c = control::makeController(kind_, p.ctrl);
    } catch (const std::exception&) {
      code = canopen::kAbortParameterIncompatible;
    }
  }
  if (code != canopen::kSdoOk) {
    ++fc_.sets_refused;
    last_refusal_ = code;
    return code;
  }
  retired_.reset();  // the controller replaced at the last cycle boundary
  next_ctrl_ = std::move(c);
  next_ = std::move(p);
  commit_ready_ = true;
  staged_flag_.set(0);
  return canopen::kSdoOk;
}

void ControllerNode::discard() {
  writeParams(running_);
  staged_flag_.set(0);
}

void ControllerNode::takeCommitted(double y) noexcept {
  // Pointer and struct swaps only: nothing is allocated or freed in the cycle.
  std::swap(ctrl_, next_ctrl_);
  retired_.swap(next_ctrl_);
  std::swap(running_, next_);
  commit_ready_ = false;
  const bool safe_changed = running_.safe_u != next_.safe_u;
  safe_u_ = std::clamp(running_.safe_u, pd::kCommandMin, pd::kCommandMax);
  missing_limit_ = running_.missing_limit;
  ++fc_.sets_applied;
  sets_applied_.set(static_cast<std::uint8_t>(fc_.sets_applied));
  if (safe_changed) push_valve_ = true;
  // Bumpless: the new controller starts from the command in effect; the setpoint ramps from here.
  if (active_ && fault_ == Fault::None) {
    ctrl_->activate(last_u_, y);
    startRamp(y);
  }
}

void ControllerNode::start(TimeUs now) {
  node_->start(now);
  node_->applyNmt(NmtCommand::Start);  // the state hook starts the slaves
}

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
      last_u_ = safe_u_;
      valve_cmd_.set(toValve(safe_u_));
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
  last_u_ = safe_u_;
  ctrl_->activate(last_u_, y);
  startRamp(y);
}

void ControllerNode::startRamp(double y) noexcept {
  const double t = run_started_ ? static_cast<double>(cycle_ - preroll_cycles_) * Ts_ : 0.0;
  const double gap = std::fabs(traj_.at(t) - y);
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

void ControllerNode::startSlave(Slave& s, TimeUs now) noexcept {
  node_->sendNmt(NmtCommand::Start, s.id);
  s.start_sent = now;
  ++fc_.nmt_starts;
}

void ControllerNode::hold(std::uint8_t reason) noexcept {
  const bool was = hold_ != 0;
  hold_ |= reason;
  if (was) return;
  node_->sendNmt(NmtCommand::EnterPreOperational, valve_.id);
  valve_.start_sent = canopen::kNever;
  ++fc_.valve_holds;
}

void ControllerNode::release(std::uint8_t reason, TimeUs now) noexcept {
  if ((hold_ & reason) == 0) return;
  hold_ = static_cast<std::uint8_t>(hold_ & ~reason);
  if (hold_ == 0) startSlave(valve_, now);
}

void ControllerNode::pushValveErrorValue() noexcept {
  // CiA 401: the valve outputs 0x6444:01 on a communication error; make it the controller's safe value.
  const std::int32_t v = toValve(safe_u_);
  auto& sdo = node_->sdoClient();
  if (sdo.busy()) return;
  push_valve_ = false;
  sdo.downloadValue<std::int32_t>(valve_.id, 0x6444, 1, v, [this](std::uint32_t code, const std::uint8_t*, std::size_t) {
    if (code != canopen::kSdoOk) ++fc_.valve_sdo_errors;
  });
}

void ControllerNode::onHeartbeatEvent(std::uint8_t id, HeartbeatEvent ev, NmtState st, TimeUs now) noexcept {
  Slave* s = id == sensor_.id ? &sensor_ : id == valve_.id ? &valve_ : nullptr;
  if (s == nullptr) return;
  const bool is_valve = s == &valve_;
  const Fault lost = is_valve ? Fault::ValveHeartbeat : Fault::SensorHeartbeat;
  const Fault state = is_valve ? Fault::ValveState : Fault::SensorState;
  const bool held = is_valve && hold_ != 0;
  switch (ev) {
    case HeartbeatEvent::Timeout:
      raise(lost, id);
      s->lost = true;
      s->start_sent = canopen::kNever;
      break;
    case HeartbeatEvent::BootUp:
      // A slave that rebooted lost its state and waits in Pre-operational: start it again (and give
      // the valve its error value again).
      if (active_) raise(state, id);
      s->lost = false;
      if (is_valve) push_valve_ = true;
      if (!held) startSlave(*s, now);
      break;
    case HeartbeatEvent::Started:
      if (s->lost) {
        // Back after a timeout: re-boot it (reset communication), then the boot-up starts it.
        s->lost = false;
        node_->sendNmt(NmtCommand::ResetCommunication, id);
        ++fc_.nmt_reboots;
      } else if (st == NmtState::Operational) {
        s->start_sent = canopen::kNever;
      } else if (st == NmtState::PreOperational && !held) {
        startSlave(*s, now);
      }
      break;
    case HeartbeatEvent::StateChanged:
      if (st == NmtState::Operational) {
        s->start_sent = canopen::kNever;
      } else if (st == NmtState::PreOperational && !held) {
        if (active_) raise(state, id);
        startSlave(*s, now);
      } else if (st == NmtState::Stopped && active_ && !held) {
        raise(state, id);
      }
      break;
  }
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

bool ControllerNode::slaveDown(Slave& s, TimeUs now) noexcept {
  const NmtState st = node_->heartbeatConsumer().remoteState(s.id);
  if (st == NmtState::Stopped) return true;
  if (st != NmtState::PreOperational) return false;
  if (s.start_sent != canopen::kNever && now - s.start_sent < kStartGraceUs) return false;
  startSlave(s, now);  // it did not follow the last start: send another
  return true;
}

void ControllerNode::poll(TimeUs now, bool usable) noexcept {
  const auto& rp = node_->rpdo(1);
  if (active_ && !usable) ++fc_.samples_missing;
  if (active_ && rp.syncsSinceReception() > missing_limit_) raise(Fault::PositionMissing);
  if (rp.conflictInLastCycle()) {
    if (++conflict_run_ >= 3) raise(Fault::SensorConflict, static_cast<std::uint8_t>(rp.cobId() & 0xFF));
  } else {
    conflict_run_ = 0;
  }
  // Polled every cycle (the heartbeat hook fires once per timeout): a fault must not clear while its
  // cause persists.
  const auto& hb = node_->heartbeatConsumer();
  if (hb.timedOut(sensor_.id)) raise(Fault::SensorHeartbeat, sensor_.id);
  if (active_) {
    if (slaveDown(sensor_, now)) raise(Fault::SensorState, sensor_.id);
    if (hb.timedOut(valve_.id)) raise(Fault::ValveHeartbeat, valve_.id);
    if (hold_ == 0) {
      if (slaveDown(valve_, now)) raise(Fault::ValveState, valve_.id);
      const auto& rv = node_->rpdo(2);
      const bool starting = valve_.start_sent != canopen::kNever && now - valve_.start_sent < kStartGraceUs;
      if (!starting && cycle_ > missing_limit_ && rv.syncsSinceReception() > missing_limit_) raise(Fault::ValvePdoMissing);
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
  if (active_ && range_run_ > missing_limit_) raise(Fault::PositionRange);
  if (active_ && running_.stuck_span_v > 0.0 && static_cast<double>(same_run_) * Ts_ >= running_.stuck_s &&
      run_u_max_ - run_u_min_ >= running_.stuck_span_v)
    raise(Fault::SensorStuck);
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
  release(kHoldSync, now);  // SYNC is back

  // Latch: the position RPDO of this cycle.
  const auto& rp = node_->rpdo(1);
  const bool fresh = rp.syncsSinceReception() == 0;  // a position arrived in the last cycle
  const std::int32_t raw = position_.get();
  const double y = pd::countsToMm(raw);
  // Plausibility (0x2022): a position outside the measuring range is no position - the controller gets
  // NaN for it (it holds the last usable one and reports it as not used) and a run of them is a fault;
  // a position that does not change while the command moves is a stuck sensor.
  // (With 1 % of the range to spare at either end: the noise of a muscle resting at an end.)
  const double margin = 0.01 * running_.range_steps;
  const bool in_range = static_cast<double>(raw) >= -margin && static_cast<double>(raw) <= running_.range_steps + margin;
  const double y_ctrl = in_range ? y : std::numeric_limits<double>::quiet_NaN();
  if (fresh && !in_range) {
    ++range_run_;
  } else if (fresh) {
    range_run_ = 0;
    if (!have_raw_ || raw != raw_last_) {
      have_raw_ = true;
      raw_last_ = raw;
      same_run_ = 0;
      run_u_min_ = run_u_max_ = last_u_;
    } else {
      ++same_run_;
    }
  }
  run_u_min_ = std::min(run_u_min_, last_u_);  // the command in effect over the run
  run_u_max_ = std::max(run_u_max_, last_u_);
  if (!active_ && fresh && in_range) {
    ctrl_->activate(last_u_, y);
    active_ = true;
  }
  if (commit_ready_) takeCommitted(y_ctrl);  // a committed parameter set: at the cycle boundary
  if (active_) {
    ++cycle_;
    run_started_ = cycle_ > preroll_cycles_;
  }
  poll(now, fresh && in_range);
  takeCauses(now);
  if (push_valve_) pushValveErrorValue();

  const double t = run_started_ ? static_cast<double>(cycle_ - preroll_cycles_) * Ts_ : 0.0;
  if (ramp_ && cycle_ >= ramp_k0_ + ramp_cycles_) ramp_ = false;
  const double yd = setpoint(t, 0);
  CycleRecord rec{static_cast<std::uint32_t>(cycle_), t, yd, y, safe_u_, 0.0, 0.0, y, 0, 0.0f};
  if (fault_ != Fault::None) {
    // Safe state: valve to its safe value every cycle until the causes have been gone long enough
    // (and SYNC, hence the valve, is back); then estimator and integrator restart (no jump).
    last_u_ = safe_u_;
    ++fc_.safe_cycles;
    if (++clear_cycles_ >= cfg_.recover_cycles && fresh && in_range && (hold_ & kHoldSync) == 0) recover(y, now);
  } else if (active_) {
    const int la = ctrl_->lookahead();
    const double yd_ahead = run_started_ ? setpoint(t + la * Ts_, la) : setpoint(0.0, la);
    const auto o = ctrl_->update(yd, yd_ahead, y_ctrl);
    if (!std::isfinite(o.u) || o.estimator_reset) {
      raise(Fault::Estimator);
      takeCauses(now);
      last_u_ = safe_u_;
    } else if (slew_) {
      // Bumpless transfer: a restarted estimator may ask for a step (the AMC's model prediction from
      // rest); the valve gets it as a ramp, until the controller's command is within reach.
      const double u = std::clamp(o.u, last_u_ - cfg_.ramp_slew_v, last_u_ + cfg_.ramp_slew_v);
      if (!ramp_ && u == o.u) slew_ = false;
      last_u_ = u;
    } else {
      last_u_ = o.u;
    }
    rec = CycleRecord{static_cast<std::uint32_t>(cycle_), t, yd, y, o.u, o.u_n, o.u_c, o.y_hat, 0, 0.0f};
  }
  if ((episode_ & kWarnMask) != 0 && ++warn_clear_ >= cfg_.recover_cycles) {
    for (Fault w : {Fault::PdoLength, Fault::SyncLength})
      if ((episode_ & bit(w)) != 0) node_->emcy().clear(emcyCode(w));
    episode_ &= ~kWarnMask;
    if (fault_ == Fault::None) reacted_at_us_ = canopen::kNever;
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
