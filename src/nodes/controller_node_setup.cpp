// The controller node's set-up: construction (the drivers, the supervisor, the loop), hooks,
// configuration on entering Operational, the slaves' boot reports. The cycle is in controller_node.cpp.
#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "canopen/eds_dictionary.hpp"
#include <stdexcept>

#include "model/inverse_fold.hpp"

namespace pamc::nodes {

namespace {
// What the MBC's setpoint governor follows, and whether its model's inverse folds, said once at its start
// (docs/CONTROL.md, "The setpoint governor", "A model whose inverse folds"); or that its model does not come to
// rest, and the MBC is its PI alone ("A model that does not come to rest").
std::string governorNote(control::ControllerConfig ctrl, const std::optional<model::Model>& own) {
  if (own) ctrl.model = *own;
  const model::HeldRest rest = control::mbcModelRest(ctrl);
  if (!rest.rests) return "mbc: the model: " + model::describeHeldRest(rest) + ": the PI alone, on the setpoint";
  const control::GovernorLimits g = control::mbcGovernor(ctrl);
  char line[256];
  if (!(g.rate_mm_s > 0.0))
    std::snprintf(line, sizeof line,
                  "mbc: no setpoint governor (mbc_rate_mm_s 0): a step goes to the inverse as it is");
  else
    std::snprintf(
        line, sizeof line,
        "mbc: the setpoint governor: %.4g mm/s, %.4g mm/s^2, %.4g mm/s^2 while the model carries the loop (%s)",
        g.rate_mm_s, g.accel_mm_s2, g.accel_carried_mm_s2,
        g.from_model ? "lowered to the model's pace" : "its fixed limits");
  const model::Interval u = control::mbcCommandRange(ctrl);
  const model::InverseFold f = model::inverseFold(ctrl.model, u.lo, u.hi);
  return f.folds ? std::string(line) + "\nmbc: the model: " + model::describeInverseFold(f) : std::string(line);
}
// Each line of a note to the log.
void logLines(const std::function<void(const std::string&)>& log, const std::string& note) {
  std::size_t from = 0;
  for (std::size_t nl; (nl = note.find('\n', from)) != std::string::npos; from = nl + 1)
    log(note.substr(from, nl - from));
  log(note.substr(from));
}
// Whole cycles of period_us in seconds s, at least one.
int recoverCycles(double s, std::uint32_t period_us) {
  return std::max(1, static_cast<int>(std::lround(s * 1e6 / period_us)));
}

}  // namespace

using canopen::NmtCommand;
using canopen::NmtState;
using canopen::SlaveEvent;
using canopen::TimeUs;

ControllerNode::ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                               std::function<TimeUs()> clock)
    : clock_(std::move(clock)), channel_cfg_(cfg.channels), fault_all_(cfg.fault_all), log_(cfg.log) {
  if (cfg.channels.empty() || cfg.channels.size() > kMaxChannels)
    throw std::invalid_argument("controller: " + std::to_string(cfg.channels.size()) + " channels (1.." +
                                std::to_string(kMaxChannels) + ")");
  // The dictionary: the EDS with the rig file's or a DCF's values as its defaults (the slaves' boot).
  const canopen::EdsFile eds = canopen::EdsFile::load(cfg.eds_path);
  const std::uint8_t id = canopen::resolveNodeId(eds, cfg.eds_path, cfg.node_id);
  node_ = std::make_unique<canopen::Node>(canopen::dictionaryFromEds(eds, id, cfg.dictionary), id, transport);
  master_ = std::make_unique<canopen::NmtMaster>(*node_);
  params_ = std::make_unique<ControllerParameters>(*node_, cfg.ctrl, cfg.build_off_cycle);
  params_->setChannels(cfg.channels.size(), [this](control::Kind k, const control::ControllerConfig& c,
                                                   std::size_t ch) { return buildFor(k, c, ch); });
  channels_.reserve(cfg.channels.size());
  for (std::size_t c = 0; c < cfg.channels.size(); ++c) addChannel(cfg, c);
  overrides_ = std::make_unique<OdOverrides>(cfg);
  overrides_->apply(node_->od(), *params_);
  configureFromOd();
  params_->installGuards();
  installHooks();
}

// Channel c: its drivers over the controller's objects and PDOs of the channel, its supervisor (the
// first reports the bus's causes), its loop.
void ControllerNode::addChannel(const ControllerNodeConfig& cfg, std::size_t c) {
  const ChannelConfig& cc = cfg.channels[c];
  const auto& lay = cc.layout;
  Channel ch;
  ch.sensor =
      std::make_unique<SensorDriver>(*node_, *master_, cc.sensor_id, lay.scaling, cfg.no_position_s, cc.position_rpdo,
                                     cc.position_object ? cc.position_object : positionObject(c));
  ch.valve =
      std::make_unique<ValveDriver>(*node_, *master_, cc.valve_id, lay.scaling, lay.feedback, lay.error_value_index,
                                    lay.error_value_sub, cc.feedback_rpdo, commandObject(c), pressureObject(c));
  if (lay.position_step_from_device) ch.sensor->readStepAtBoot();
  ch.valve->errorValueAtBoot([this] { return params_->safeCommand(); });
  const auto number = static_cast<std::uint8_t>(cfg.channels.size() > 1 ? c + 1 : 0);
  // Its recovery in cycles of the design's 1 ms until configureFromOd, later in the constructor, sets it
  // from 0x1006 as the overrides leave it.
  ch.faults = std::make_unique<FaultSupervisor>(*node_, recoverCycles(cfg.recover_s, 1000), number, c == 0);
  ch.loop = std::make_unique<ControlLoop>(cfg.ramp_mm_per_s, cfg.ramp_slew_v);
  ch.partner = cc.partner;
  ch.offset_v = cc.command_offset_v;
  ch.sensor->bind();
  ch.valve->bind();
  channels_.push_back(std::move(ch));
}

// Channel c's controller of a parameter set: its own kind and model where the rig file gives them.
std::unique_ptr<control::Controller> ControllerNode::buildFor(control::Kind kind, const control::ControllerConfig& ctrl,
                                                              std::size_t c) const {
  const ChannelConfig& cc = channel_cfg_[c];
  if (cc.kind < 0 && !cc.model) return control::makeController(kind, ctrl);
  control::ControllerConfig own = ctrl;
  if (cc.model) own.model = *cc.model;
  return control::makeController(cc.kind >= 0 ? static_cast<control::Kind>(cc.kind) : kind, own);
}

void ControllerNode::installHooks() {
  node_->onSync([this](std::uint8_t counter, TimeUs now) { onSync(counter, now); });
  master_->onEvent([this](std::uint8_t id, SlaveEvent ev, TimeUs) { onSlaveEvent(id, ev); });
  node_->onErrorFrame([this](const canopen::Frame& f, TimeUs) {
    for (auto& c : channels_) c.faults->onErrorFrame(f);
  });
  // SYNC consumer: without SYNC no cycle runs, so act in the hook: safe value, EMCY, and the valves to
  // Pre-operational, where they output their error values (they would hold the last command otherwise).
  node_->onSyncTimeout([this](TimeUs now) {
    raiseAll(Fault::SyncLost);
    for (auto& c : channels_) takeCauses(c, now);
    holdValves(ValveDriver::kHoldSync);
  });
  node_->onCollision([this](const canopen::Frame& f, TimeUs now) {
    ++collisions_;
    collision_pub_.store(f.id, std::memory_order_relaxed);
    raiseAll(Fault::IdCollision, static_cast<std::uint8_t>(f.id & 0xFF));
    for (auto& c : channels_) takeCauses(c, now);
    // The other node may command the valves too: keep them in Pre-operational until the collision is gone.
    holdValves(ValveDriver::kHoldCollision);
  });
  installStateHook();
  // A reset restores the EDS defaults: put the command line's choices back.
  node_->onReset([this](NmtCommand, TimeUs) {
    master_->end();
    overrides_->apply(node_->od(), *params_);
  });
}

void ControllerNode::installStateHook() {
  node_->onStateChange([this](NmtState from, NmtState to, TimeUs now) {
    if (from == NmtState::Initialising && to == NmtState::PreOperational) {
      // Booted (at start or after a reset): a master enters Operational by itself unless 0x1F80 bit 2
      // says to wait for an NMT start - so a reset brings the rig back up without an operator.
      const auto* startup = node_->od().find(canopen::kObjStartup, 0);
      if (startup == nullptr || (startup->get<std::uint32_t>() & canopen::kStartupNoSelfStart) == 0)
        node_->applyNmt(NmtCommand::Start);  // boots and starts the slaves (below)
      return;
    }
    if (to == NmtState::Operational) {
      onOperational(now);
    } else if (from == NmtState::Operational) {
      // No more setpoints from here: the valve goes to its error value instead of holding the last one.
      // The loop stops (PDOs do not move outside Operational); NMT start configures it afresh.
      holdValves(ValveDriver::kHoldSelf);
      master_->end();
      for (auto& c : channels_) {
        c.sensor->onLeftOperational();
        c.loop->stop();
      }
    }
  });
}

FaultCounters ControllerNode::channelCounters(std::size_t i) const noexcept {
  const Channel& c = ch(i);
  const auto& f = c.faults->counters();
  FaultCounters n;
  n.episodes = f.episodes;
  n.recoveries = f.recoveries;
  n.safe_cycles = f.safe_cycles;
  n.warnings = f.warnings;
  n.samples_missing = c.sensor->samplesMissing();
  n.positions = c.sensor->positions();
  n.valve_sdo_errors = c.valve->sdoErrors();
  return n;
}

FaultCounters ControllerNode::faultCounters() const noexcept {
  FaultCounters c;
  for (std::size_t i = 0; i < channels_.size(); ++i) {
    const FaultCounters n = channelCounters(i);
    c.episodes += n.episodes;
    c.recoveries += n.recoveries;
    c.safe_cycles += n.safe_cycles;
    c.warnings += n.warnings;
    c.samples_missing += n.samples_missing;
    c.positions += n.positions;
    c.valve_sdo_errors += n.valve_sdo_errors;
  }
  c.collisions = collisions_;
  c.last_collision_cob = collision_pub_.load(std::memory_order_relaxed);
  c.nmt_starts = master_->counters().starts;
  c.nmt_reboots = master_->counters().reboots;
  c.valve_holds = master_->counters().holds;
  c.slave_boots = master_->counters().boots;
  c.slave_boot_failures = master_->counters().boot_failures;
  c.sets_applied = params_->applied();
  c.sets_refused = params_->refused();
  return c;
}

Fault ControllerNode::fault() const noexcept {
  for (const auto& c : channels_)
    if (const Fault f = c.faults->published(); f != Fault::None) return f;
  return Fault::None;
}

bool ControllerNode::running() const noexcept {
  for (const auto& c : channels_)
    if (!c.loop->running()) return false;
  return true;
}

std::uint64_t ControllerNode::faultsRaised() const noexcept {
  std::uint64_t n = 0;
  for (const auto& c : channels_) n += c.faults->raised();
  return n;
}

std::uint32_t ControllerNode::episodeCauses() const noexcept {
  std::uint32_t e = 0;
  for (const auto& c : channels_) e |= c.faults->episode();
  return e;
}

TimeUs ControllerNode::reactedAtUs() const noexcept {
  TimeUs t = canopen::kNever;
  for (const auto& c : channels_) t = std::min(t, c.faults->reactedAt());
  return t;
}

void ControllerNode::configureFromOd() {
  auto& od = node_->od();
  const ControllerNodeConfig& cfg = overrides_->config();
  ParameterSet p = params_->read();
  std::string why;
  if (params_->check(p, &why) != canopen::kSdoOk)
    throw std::invalid_argument(cfg.eds_path + ": parameter set refused: " + why);
  const std::uint32_t period_us = od.ref<std::uint32_t>(0x1006, 0).get();
  if (period_us == 0) throw std::invalid_argument(cfg.eds_path + ": 0x1006 communication cycle period is 0");
  // Build everything first, then swap: a failure leaves the running controllers in place.
  const double Ts = period_us * 1e-6;
  p.ctrl.Ts = Ts;
  p.ctrl.delay_cycles = cfg.delay_cycles;  // 2 on this rig: y_k reflects u_{k-3} (controller_node.hpp)
  const auto kind = static_cast<control::Kind>(od.ref<std::uint8_t>(0x2010, 0).get());
  auto traj = trajectoryFromOd(od);
  if (overrides_->trajectoryOverridden()) traj = cfg.trajectory;  // shapes the OD cannot hold
  std::vector<std::unique_ptr<control::Controller>> fresh;
  std::vector<model::OperatingRange> ranges;
  std::vector<std::string> governors;
  for (std::size_t c = 0; c < channels_.size(); ++c) {
    fresh.push_back(buildFor(kind, p.ctrl, c));
    const ChannelConfig& cc = channel_cfg_[c];
    const bool model_based = control::usesModel(cc.kind >= 0 ? static_cast<control::Kind>(cc.kind) : kind);
    ranges.push_back(model_based ? (cc.model ? *cc.model : p.ctrl.model).range() : model::OperatingRange{});
    const bool mbc = (cc.kind >= 0 ? static_cast<control::Kind>(cc.kind) : kind) == control::Kind::Mbc;
    governors.push_back(mbc ? governorNote(p.ctrl, cc.model) : std::string());
  }
  params_->adopt(std::move(p), kind);
  for (auto& c : channels_) c.faults->setRecoverCycles(recoverCycles(cfg.recover_s, period_us));
  for (std::size_t c = 0; c < channels_.size(); ++c) {
    const ChannelConfig& cc = channel_cfg_[c];
    const auto k = cc.kind >= 0 ? static_cast<control::Kind>(cc.kind) : kind;
    if (k == control::Kind::Mbc && !ranges[c].known && log_)
      log_(
          "mbc: the model records no range it was identified on (model.json without 'range'): its feedforward is "
          "used everywhere, with no fallback to the PI");
    governor_said_.resize(channels_.size());
    if (k == control::Kind::Mbc && log_ && governors[c] != governor_said_[c]) logLines(log_, governors[c]);
    governor_said_[c] = governors[c];
    const control::Trajectory own =
        (cc.trajectory ? *cc.trajectory : traj).mapped(cc.setpoint_scale, cc.setpoint_offset);
    channels_[c].loop->configure(std::move(fresh[c]), k, own, Ts, cfg.preroll_s, params_->safeCommand());
    channels_[c].loop->watchRange(ranges[c]);
    channels_[c].valve->zero();
  }
}

void ControllerNode::onOperational(TimeUs now) {
  // Parameters set over SDO take effect here; a set that does not configure keeps the running
  // controllers and raises a fault instead of escaping into the event loop.
  try {
    configureFromOd();
  } catch (const std::exception&) {
    params_->countRefused();
    raiseAll(Fault::Estimator);
  }
  // Boots (checks and configures) the slaves that need it and starts those that may run; the valves
  // start once nothing else holds them.
  for (auto& c : channels_) c.sensor->onOperational(now);
  master_->begin(now);
  releaseValves(ValveDriver::kHoldSelf, now);
  // A valve's boot writes its error value (its configuration); one the master does not boot gets it
  // from the cycle.
  for (auto& c : channels_)
    if (!master_->boots(c.valve->id())) c.valve->errorValueDue();
}

void ControllerNode::takeCommitted() noexcept {
  std::unique_ptr<control::Controller>* ctrls[kMaxChannels] = {};
  for (std::size_t c = 0; c < channels_.size(); ++c) ctrls[c] = &channels_[c].loop->controller();
  const bool safe_changed = params_->take(ctrls);
  for (auto& c : channels_) {
    if (safe_changed) c.valve->errorValueDue();  // the valve's error value follows the safe value
    // Bumpless: the new controller starts from the command in effect; the setpoint ramps from here.
    if (c.loop->active() && c.faults->fault() == Fault::None) c.loop->restartFrom(c.sample.y_ctrl);
  }
}

void ControllerNode::start(TimeUs now) { node_->start(now); }  // the state hook goes on to Operational

// A slave's event goes to every channel's driver of that slave; its boot report is logged once.
void ControllerNode::onSlaveEvent(std::uint8_t id, SlaveEvent ev) {
  const char* role = nullptr;
  const TimeUs now = node_->now();
  for (auto& c : channels_) {
    Driver* drivers[] = {c.sensor.get(), c.valve.get()};
    for (Driver* d : drivers) {
      if (d->id() != id) continue;
      if (role == nullptr) role = d->role();
      d->onEvent(ev, now, *c.faults, c.loop->active());
    }
    if (ev == SlaveEvent::BootFailed) takeCauses(c, now);
  }
  if (role != nullptr) logSlaveEvent(role, id, ev);
}

void ControllerNode::logSlaveEvent(const char* role, std::uint8_t id, SlaveEvent ev) const {
  if (!log_) return;
  const std::string who = std::string(role) + " (node " + std::to_string(id) + ")";
  if (ev == SlaveEvent::Configured) log_(who + ": identity checked, configuration written and read back");
  if (ev == SlaveEvent::KeptAlive)
    log_(who + ": kept alive (Operational, heartbeat live): identity checked, not reset or configured again");
  if (ev != SlaveEvent::BootFailed) return;
  if (const auto* e = master_->bootError(id)) {
    char code[32] = "";
    if (e->abort_code) std::snprintf(code, sizeof code, " (SDO abort 0x%08X)", e->abort_code);
    log_(who + " not started, " + canopen::bootStepName(e->step) + ": " + e->text + code);
  }
}

}  // namespace pamc::nodes
