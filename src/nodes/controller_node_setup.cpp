// The controller node's set-up: construction, hooks, the command line's choices and the rig's layout
// in the dictionary, configuration on entering Operational, the slaves' boot reports. The cycle and
// the fault handling are in controller_node.cpp.
#include "nodes/controller_node.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

#include "nodes/process_data.hpp"

namespace pamc::nodes {

using canopen::NmtCommand;
using canopen::NmtState;
using canopen::SlaveEvent;
using canopen::TimeUs;

namespace {
std::uint32_t withNode(std::uint32_t hb, std::uint8_t id) { return (static_cast<std::uint32_t>(id) << 16) | (hb & 0xFFFFu); }
}  // namespace


ControllerNode::ControllerNode(const ControllerNodeConfig& cfg, canopen::Transport& transport,
                               std::function<TimeUs()> clock)
    : cfg_(cfg), clock_(std::move(clock)) {
  node_ = canopen::Node::fromEds(cfg.eds_path, transport, cfg.node_id);
  master_ = std::make_unique<canopen::NmtMaster>(*node_);
  master_->addSlave(cfg.sensor_id);
  master_->addSlave(cfg.valve_id);
  scaling_ = cfg.layout.scaling;
  if (cfg.layout.sensor_boot || cfg.layout.position_step_from_device) {
    canopen::SlaveBoot b = cfg.layout.sensor_boot.value_or(canopen::SlaveBoot{});
    if (cfg.layout.position_step_from_device) {
      b.assignment |= canopen::kAssignBoot;
      // CiA 406: 0x6005:01 is the measuring step in nm; the loop sees it before the sensor starts.
      b.reads.insert(b.reads.begin(), canopen::SlaveBoot::Read{0x6005, 1, [this](const std::uint8_t* d, std::size_t len, std::string* why) {
        std::uint32_t nm = 0;
        for (std::size_t i = 0; i < len && i < 4; ++i) nm |= static_cast<std::uint32_t>(d[i]) << (8 * i);
        if (len != 4 || nm == 0) {
          *why = "measuring step " + std::to_string(nm) + " nm (" + std::to_string(len) + " bytes) is not a step";
          return false;
        }
        scaling_.position_step_mm = nm * 1e-6;
        return true;
      }});
    }
    master_->setBoot(cfg.sensor_id, std::move(b));
  }
  if (cfg.layout.valve_boot) master_->setBoot(cfg.valve_id, *cfg.layout.valve_boot);
  params_ = std::make_unique<ControllerParameters>(*node_, cfg_.ctrl, cfg_.build_off_cycle);
  applyOverrides();
  position_ = node_->od().ref<std::int32_t>(0x3000, 0);
  valve_cmd_ = node_->od().ref<std::int16_t>(0x3002, 0);
  configureFromOd();
  params_->installGuards();
  installHooks();
}

void ControllerNode::installHooks() {
  node_->onSync([this](std::uint8_t counter, TimeUs now) { onSync(counter, now); });
  master_->onEvent([this](std::uint8_t id, SlaveEvent ev, TimeUs) { onSlaveEvent(id, ev); });
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
    if (from == NmtState::Initialising && to == NmtState::PreOperational) {
      // Booted (at start or after a reset): a master enters Operational by itself unless 0x1F80 bit 2
      // says to wait for an NMT start - so a reset brings the rig back up without an operator.
      const auto* startup = node_->od().find(0x1F80, 0);
      if (startup == nullptr || (startup->get<std::uint32_t>() & canopen::kStartupNoSelfStart) == 0)
        node_->applyNmt(NmtCommand::Start);  // boots and starts the slaves (below)
      return;
    }
    if (to == NmtState::Operational) {
      onOperational(now);
    } else if (from == NmtState::Operational) {
      // No more setpoints from here: the valve goes to its error value instead of holding the last one.
      // The loop stops (PDOs do not move outside Operational); NMT start configures it afresh.
      hold(kHoldSelf);
      master_->end();
      operational_at_ = canopen::kNever;
      active_ = run_started_ = false;
      ramp_ = slew_ = false;
    }
  });
  // A reset restores the EDS defaults: put the command line's choices back.
  node_->onReset([this](NmtCommand, TimeUs) {
    master_->end();
    applyOverrides();
  });
}

FaultCounters ControllerNode::faultCounters() const noexcept {
  FaultCounters c = fc_;
  c.nmt_starts = master_->counters().starts;
  c.nmt_reboots = master_->counters().reboots;
  c.valve_holds = master_->counters().holds;
  c.slave_boots = master_->counters().boots;
  c.slave_boot_failures = master_->counters().boot_failures;
  c.sets_applied = params_->applied();
  c.sets_refused = params_->refused();
  return c;
}

void ControllerNode::applyOverrides() {
  auto& od = node_->od();
  // Command-line choices go into the dictionary, so SDO reads show what runs.
  if (cfg_.kind >= 0) od.ref<std::uint8_t>(0x2010, 0).set(static_cast<std::uint8_t>(cfg_.kind));
  if (cfg_.gains_from_config) params_->writeGains(cfg_.ctrl);
  params_->writeModel(cfg_.ctrl.model.core());
  if (cfg_.has_trajectory) traj_override_ = !trajectoryToOd(od, cfg_.trajectory);
  if (cfg_.period_us) {
    od.ref<std::uint32_t>(0x1006, 0).set(cfg_.period_us);
    // The synchronous window keeps its share of the period (0x1007 default: 800 of 1000 us).
    if (auto* w = od.find(0x1007, 0)) w->set<std::uint32_t>(cfg_.period_us / 5 * 4);
  }
  // Where the slaves' process data are, and whose heartbeats to watch.
  const auto& lay = cfg_.layout;
  if (lay.sensor_cob) od.ref<std::uint32_t>(0x1400, 1).set(lay.sensor_cob);
  if (lay.feedback_cob) od.ref<std::uint32_t>(0x1401, 1).set(lay.feedback_cob);
  if (!lay.feedback) {
    auto cob = od.ref<std::uint32_t>(0x1401, 1);
    cob.set(cob.get() | 0x80000000u);  // no feedback PDO: RPDO2 off
  }
  if (lay.valve_cob) od.ref<std::uint32_t>(0x1800, 1).set(lay.valve_cob);
  for (auto [sub, id] : {std::pair<std::uint8_t, std::uint8_t>{1, cfg_.sensor_id}, {2, cfg_.valve_id}}) {
    auto hb = od.ref<std::uint32_t>(0x1016, sub);
    hb.set(withNode(hb.get(), id));
  }
  if (lay.startup) od.ref<std::uint32_t>(0x1F80, 0).set(lay.startup);
  // 0x1F81 for the slaves (the master reads it when it begins): the rig's boot settings, or a plain slave
  // (reset when it comes back after a heartbeat loss) for a node-ID the EDS does not assign.
  for (auto [id, boot] : {std::pair<std::uint8_t, const std::optional<canopen::SlaveBoot>*>{cfg_.sensor_id, &lay.sensor_boot},
                          {cfg_.valve_id, &lay.valve_boot}}) {
    auto* e = od.find(0x1F81, id);
    if (e == nullptr) continue;
    std::uint32_t a = e->get<std::uint32_t>();
    if (*boot) a = (*boot)->assignment;
    else if (a == 0) a = canopen::kAssignSlave;
    if (id == cfg_.sensor_id && lay.position_step_from_device) a |= canopen::kAssignBoot;
    e->set<std::uint32_t>(a);
  }
  if (!cfg_.produce_sync) {
    auto cob = od.ref<std::uint32_t>(0x1005, 0);
    cob.set(cob.get() & ~0x40000000u);  // consume SYNC from another master
  }
}

void ControllerNode::configureFromOd() {
  auto& od = node_->od();
  ParameterSet p = params_->read();
  std::string why;
  if (params_->check(p, &why) != canopen::kSdoOk) throw std::invalid_argument(cfg_.eds_path + ": parameter set refused: " + why);
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
  params_->adopt(std::move(p), kind);
  active_ = false;
  run_started_ = false;
  ramp_ = false;
  cycle_ = 0;
  preroll_cycles_ = static_cast<std::uint64_t>(std::llround(cfg_.preroll_s / Ts_));
  last_u_ = params_->safeCommand();
  valve_cmd_.set(0);
  run_time_pub_.store(0.0, std::memory_order_relaxed);
}

void ControllerNode::onOperational(TimeUs now) {
  // Parameters set over SDO take effect here; a set that does not configure keeps the running
  // controller and raises a fault instead of escaping into the event loop.
  try {
    configureFromOd();
  } catch (const std::exception&) {
    params_->countRefused();
    raise(Fault::Estimator);
  }
  // Boots (checks and configures) the slaves that need it and starts those that may run; the valve
  // starts once nothing else holds it.
  operational_at_ = now;
  position_cob_pub_.store(node_->rpdo(1).cobId() & 0x7FFu, std::memory_order_relaxed);
  master_->begin(now);
  release(kHoldSelf, now);
  push_valve_ = true;
  pushValveErrorValue();
}

void ControllerNode::takeCommitted(double y) noexcept {
  if (params_->take(ctrl_)) push_valve_ = true;  // the valve's error value follows the safe value
  // Bumpless: the new controller starts from the command in effect; the setpoint ramps from here.
  if (active_ && fault_ == Fault::None) {
    ctrl_->activate(last_u_, y);
    startRamp(y);
  }
}

void ControllerNode::start(TimeUs now) { node_->start(now); }  // the state hook goes on to Operational

void ControllerNode::onSlaveEvent(std::uint8_t id, SlaveEvent ev) {
  const bool is_valve = id == cfg_.valve_id;
  const char* role = is_valve ? "valve" : "sensor";
  switch (ev) {
    case SlaveEvent::Configured:
      if (cfg_.log) cfg_.log(std::string(role) + " (node " + std::to_string(id) + "): identity checked, configuration written and read back");
      break;
    case SlaveEvent::BootFailed: {
      const auto* e = master_->bootError(id);
      raise(Fault::SlaveBoot, id);
      takeCauses(node_->now());
      if (cfg_.log && e) {
        char code[32] = "";
        if (e->abort_code) std::snprintf(code, sizeof code, " (SDO abort 0x%08X)", e->abort_code);
        cfg_.log(std::string(role) + " (node " + std::to_string(id) + ") not started: " + e->text + code);
      }
      break;
    }
    case SlaveEvent::Lost:
      raise(is_valve ? Fault::ValveHeartbeat : Fault::SensorHeartbeat, id);
      break;
    case SlaveEvent::BootUp:
      // It lost its state (the master starts it again); the valve needs its error value again.
      if (is_valve) push_valve_ = true;
      if (active_) raise(is_valve ? Fault::ValveState : Fault::SensorState, id);
      break;
    case SlaveEvent::LeftOperational:
    case SlaveEvent::Stopped:
      if (active_) raise(is_valve ? Fault::ValveState : Fault::SensorState, id);
      break;
  }
}


}  // namespace pamc::nodes
