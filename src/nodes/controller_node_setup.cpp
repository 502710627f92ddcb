// The controller node's set-up: construction (the drivers, the supervisor, the loop), hooks,
// configuration on entering Operational, the slaves' boot reports. The cycle is in controller_node.cpp.
#include "nodes/controller_node.hpp"

#include <cstdio>

#include "canopen/eds_dictionary.hpp"
#include <stdexcept>

namespace pamc::nodes {

using canopen::NmtCommand;
using canopen::NmtState;
using canopen::SlaveEvent;
using canopen::TimeUs;

ControllerNode::ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                               std::function<TimeUs()> clock)
    : clock_(std::move(clock)), log_(cfg.log) {
  // The dictionary: the EDS with the rig file's or a DCF's values as its defaults (the slaves' boot).
  const canopen::EdsFile eds = canopen::EdsFile::load(cfg.eds_path);
  const std::uint8_t id = canopen::resolveNodeId(eds, cfg.eds_path, cfg.node_id);
  node_ = std::make_unique<canopen::Node>(canopen::dictionaryFromEds(eds, id, cfg.dictionary), id, transport);
  master_ = std::make_unique<canopen::NmtMaster>(*node_);
  const auto& lay = cfg.layout;
  sensor_ = std::make_unique<SensorDriver>(*node_, *master_, cfg.sensor_id, lay.scaling, cfg.no_position_s);
  valve_ = std::make_unique<ValveDriver>(*node_, *master_, cfg.valve_id, lay.scaling, lay.feedback,
                                         lay.error_value_index, lay.error_value_sub);
  if (lay.position_step_from_device) sensor_->readStepAtBoot();
  params_ = std::make_unique<ControllerParameters>(*node_, cfg.ctrl, cfg.build_off_cycle);
  valve_->errorValueAtBoot([this] { return params_->safeCommand(); });
  overrides_ = std::make_unique<OdOverrides>(cfg);
  overrides_->apply(node_->od(), *params_);
  faults_ = std::make_unique<FaultSupervisor>(*node_, cfg.recover_cycles);
  loop_ = std::make_unique<ControlLoop>(cfg.ramp_mm_per_s, cfg.ramp_slew_v);
  sensor_->bind();
  valve_->bind();
  configureFromOd();
  params_->installGuards();
  installHooks();
}

void ControllerNode::installHooks() {
  node_->onSync([this](std::uint8_t counter, TimeUs now) { onSync(counter, now); });
  master_->onEvent([this](std::uint8_t id, SlaveEvent ev, TimeUs) { onSlaveEvent(id, ev); });
  node_->onErrorFrame([this](const canopen::Frame& f, TimeUs) { faults_->onErrorFrame(f); });
  // SYNC consumer: without SYNC no cycle runs, so act in the hook: safe value, EMCY, and the valve to
  // Pre-operational, where it outputs its error value (it would hold the last command otherwise).
  node_->onSyncTimeout([this](TimeUs now) {
    faults_->raise(Fault::SyncLost);
    takeCauses(now);
    valve_->hold(ValveDriver::kHoldSync);
  });
  node_->onCollision([this](const canopen::Frame& f, TimeUs now) {
    ++collisions_;
    collision_pub_.store(f.id, std::memory_order_relaxed);
    faults_->raise(Fault::IdCollision, static_cast<std::uint8_t>(f.id & 0xFF));
    takeCauses(now);
    // The other node may command the valve too: keep it in Pre-operational until the collision is gone.
    valve_->hold(ValveDriver::kHoldCollision);
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
      valve_->hold(ValveDriver::kHoldSelf);
      master_->end();
      sensor_->onLeftOperational();
      loop_->stop();
    }
  });
}

FaultCounters ControllerNode::faultCounters() const noexcept {
  FaultCounters c;
  const auto& f = faults_->counters();
  c.episodes = f.episodes;
  c.recoveries = f.recoveries;
  c.safe_cycles = f.safe_cycles;
  c.warnings = f.warnings;
  c.samples_missing = sensor_->samplesMissing();
  c.positions = sensor_->positions();
  c.collisions = collisions_;
  c.last_collision_cob = collision_pub_.load(std::memory_order_relaxed);
  c.valve_sdo_errors = valve_->sdoErrors();
  c.nmt_starts = master_->counters().starts;
  c.nmt_reboots = master_->counters().reboots;
  c.valve_holds = master_->counters().holds;
  c.slave_boots = master_->counters().boots;
  c.slave_boot_failures = master_->counters().boot_failures;
  c.sets_applied = params_->applied();
  c.sets_refused = params_->refused();
  return c;
}

void ControllerNode::configureFromOd() {
  auto& od = node_->od();
  const ControllerNodeConfig& cfg = overrides_->config();
  ParameterSet p = params_->read();
  std::string why;
  if (params_->check(p, &why) != canopen::kSdoOk) throw std::invalid_argument(cfg.eds_path + ": parameter set refused: " + why);
  const std::uint32_t period_us = od.ref<std::uint32_t>(0x1006, 0).get();
  if (period_us == 0) throw std::invalid_argument(cfg.eds_path + ": 0x1006 communication cycle period is 0");
  // Build everything first, then swap: a failure leaves the running controller in place.
  const double Ts = period_us * 1e-6;
  p.ctrl.Ts = Ts;
  p.ctrl.delay_cycles = cfg.delay_cycles;  // 2 on this rig: y_k reflects u_{k-3} (controller_node.hpp)
  const auto kind = static_cast<control::Kind>(od.ref<std::uint8_t>(0x2010, 0).get());
  auto traj = trajectoryFromOd(od);
  if (overrides_->trajectoryOverridden()) traj = cfg.trajectory;  // shapes the OD cannot hold
  auto fresh_ctrl = control::makeController(kind, p.ctrl);
  const model::OperatingRange range = control::usesModel(kind) ? p.ctrl.model.range() : model::OperatingRange{};
  if (kind == control::Kind::Mbc && !range.known && log_)
    log_("mbc: the model records no range it was identified on (model.json without 'range'): its feedforward is "
         "used everywhere, with no fallback to the PI");
  params_->adopt(std::move(p), kind);
  loop_->configure(std::move(fresh_ctrl), kind, traj, Ts, cfg.preroll_s, params_->safeCommand());
  loop_->watchRange(range);
  valve_->zero();
}

void ControllerNode::onOperational(TimeUs now) {
  // Parameters set over SDO take effect here; a set that does not configure keeps the running
  // controller and raises a fault instead of escaping into the event loop.
  try {
    configureFromOd();
  } catch (const std::exception&) {
    params_->countRefused();
    faults_->raise(Fault::Estimator);
  }
  // Boots (checks and configures) the slaves that need it and starts those that may run; the valve
  // starts once nothing else holds it.
  sensor_->onOperational(now);
  master_->begin(now);
  valve_->release(ValveDriver::kHoldSelf, now);
  // The valve's boot writes its error value (its configuration); one the master does not boot gets it
  // from the cycle.
  if (!master_->boots(valve_->id())) valve_->errorValueDue();
}

void ControllerNode::takeCommitted(double y) noexcept {
  if (params_->take(loop_->controller())) valve_->errorValueDue();  // the valve's error value follows the safe value
  // Bumpless: the new controller starts from the command in effect; the setpoint ramps from here.
  if (loop_->active() && faults_->fault() == Fault::None) loop_->restartFrom(y);
}

void ControllerNode::start(TimeUs now) { node_->start(now); }  // the state hook goes on to Operational

// Kept alive and running, the valve was not configured by this boot: its error value goes out now -
// the safe value may have changed since it was configured - unless the SDO client is busy (then from
// the cycle).
void ControllerNode::valveKeptAlive() {
  valve_->errorValueDue();
  valve_->pushErrorValue(params_->safeCommand());
}

void ControllerNode::onSlaveEvent(std::uint8_t id, SlaveEvent ev) {
  const bool is_valve = id == valve_->id();
  const char* role = is_valve ? "valve" : "sensor";
  switch (ev) {
    case SlaveEvent::Configured:
      if (!is_valve) sensor_->onBooted(node_->now());
      if (log_) log_(std::string(role) + " (node " + std::to_string(id) + "): identity checked, configuration written and read back");
      break;
    case SlaveEvent::KeptAlive:
      if (is_valve) valveKeptAlive();
      else sensor_->onBooted(node_->now());
      if (log_)
        log_(std::string(role) + " (node " + std::to_string(id) +
             "): kept alive (Operational, heartbeat live): identity checked, not reset or configured again");
      break;
    case SlaveEvent::BootFailed: {
      const auto* e = master_->bootError(id);
      faults_->raise(Fault::SlaveBoot, id);
      takeCauses(node_->now());
      if (log_ && e) {
        char code[32] = "";
        if (e->abort_code) std::snprintf(code, sizeof code, " (SDO abort 0x%08X)", e->abort_code);
        log_(std::string(role) + " (node " + std::to_string(id) + ") not started, " + canopen::bootStepName(e->step) + ": " +
             e->text + code);
      }
      break;
    }
    case SlaveEvent::Lost:
      faults_->raise(is_valve ? Fault::ValveHeartbeat : Fault::SensorHeartbeat, id);
      break;
    case SlaveEvent::BootUp:
      // It lost its state (the master boots and starts it again; the boot writes the valve's error
      // value, the cycle for a valve the master does not boot).
      if (is_valve && !master_->boots(id)) valve_->errorValueDue();
      if (loop_->active()) faults_->raise(is_valve ? Fault::ValveState : Fault::SensorState, id);
      break;
    case SlaveEvent::LeftOperational:
    case SlaveEvent::Stopped:
      if (loop_->active()) faults_->raise(is_valve ? Fault::ValveState : Fault::SensorState, id);
      break;
  }
}

}  // namespace pamc::nodes
