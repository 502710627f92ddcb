#include "nodes/emulator_node.hpp"

#include "nodes/process_data.hpp"

#include <algorithm>
#include <cmath>

namespace pamc::nodes {

using canopen::Frame;
using canopen::NmtState;
using canopen::TimeUs;

EmulatorNodes::EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport)
    : cfg_(cfg),
      bus_(transport),
      sensor_link_(*this, transport, true),
      valve_link_(*this, transport, false),
      plant_(cfg.plant),
      rng_(cfg.seed) {
  sensor_ = canopen::Node::fromEds(cfg.sensor_eds, sensor_link_, cfg.sensor_id);
  valve_ = canopen::Node::fromEds(cfg.valve_eds, valve_link_, cfg.valve_id);
  position_ = sensor_->od().ref<std::int32_t>(cfg.position_index, cfg.position_sub);
  pressure_ = valve_->od().ref<std::int16_t>(cfg.pressure_index, cfg.pressure_sub);
  command_ = valve_->od().ref<std::int16_t>(cfg.command_index, cfg.command_sub);
  error_mode_ = valve_->od().ref<std::uint8_t>(0x6443, cfg.command_sub);
  error_value_ = valve_->od().ref<std::int32_t>(0x6444, cfg.command_sub);
  scalingFromDevices();
  sync_cob_ = sensor_->od().ref<std::uint32_t>(0x1005, 0).get() & 0x7FFu;
  pdo_cob_ = sensor_->od().ref<std::uint32_t>(0x1800, 1).get() & 0x7FFu;
  master_hb_ = valve_->od().find(0x1016, 1);
  // The valve monitors the SYNC with the emulator's period (1.5 periods without one: error value).
  const auto period_us = static_cast<std::uint32_t>(std::lround(cfg_.plant.Ts * 1e6));
  auto monitor_sync = [this, period_us] {
    if (auto* e = valve_->od().find(0x1006, 0)) e->set<std::uint32_t>(period_us);
  };
  monitor_sync();
  valve_->onReset([monitor_sync](canopen::NmtCommand, TimeUs) { monitor_sync(); });
  valve_->onStateChange([this](NmtState, NmtState, TimeUs now) { updateValve(now); });
  valve_->onSyncTimeout([this](TimeUs now) { updateValve(now); });
  valve_->onHeartbeat([this](std::uint8_t id, canopen::HeartbeatEvent ev, NmtState, TimeUs now) {
    if (id == masterId() && ev == canopen::HeartbeatEvent::Timeout) updateValve(now);
  });
  // The valve holds its command at 0 V (vented) until the controller sends one.
  plant_.reset(pd::kCommandMin, 0.0);  // vented: 0 V at the valve
  position_.set(cfg_.scaling.positionCounts(plant_.position()));
}

void EmulatorConfig::useProfileDevices(const std::string& od_dir) {
  sensor_eds = od_dir + "/profile/encoder406.eds";
  valve_eds = od_dir + "/profile/analog401.eds";
  sensor_id = valve_id = 0;  // theirs: 16 and 32
  position_index = 0x6004, position_sub = 0;
  command_index = 0x6411, command_sub = 2;    // the valve on output 2
  pressure_index = 0x6401, pressure_sub = 2;  // the pressure sensor on input 2
  scaling = pd::Scaling{};  // what the devices' dictionaries say replaces it (scalingFromDevices)
}

EmulatorConfig EmulatorConfig::profileDevices(const std::string& od_dir) {
  EmulatorConfig e;
  e.useProfileDevices(od_dir);
  return e;
}

// How the devices count, from their own dictionaries: the sensor's measuring step (CiA 406 0x6005:01,
// nm), the valve's and the pressure input's full scale (the HighLimit of their EDS entries; 16-bit
// full scale without one).
void EmulatorNodes::scalingFromDevices() {
  if (const auto* step = sensor_->od().find(0x6005, 1)) cfg_.scaling.position_step_mm = step->asDouble() * 1e-6;
  std::int64_t full = 0;
  if (const auto* c = valve_->od().find(cfg_.command_index, cfg_.command_sub); c && c->highLimit(full) && full > 0)
    cfg_.scaling.command_full_counts = static_cast<double>(full);
  if (const auto* p = valve_->od().find(cfg_.pressure_index, cfg_.pressure_sub); p && p->highLimit(full) && full > 0)
    cfg_.scaling.pressure_full_counts = static_cast<double>(full);
}

// The master whose heartbeat the valve watches: 0x1016:01, as a master may have written it.
std::uint8_t EmulatorNodes::masterId() const {
  return master_hb_ ? static_cast<std::uint8_t>((master_hb_->asUnsigned() >> 16) & 0x7F) : 0;
}

void EmulatorNodes::start(TimeUs now) {
  now_us_ = now;
  sensor_->start(now);
  valve_->start(now);
}

bool EmulatorNodes::sensorSilent() const {
  if (inj_.sensor_silent || rebooting_) return true;
  const double t = time();
  return cfg_.sensor_silent_at_s >= 0 && t >= cfg_.sensor_silent_at_s &&
         t < cfg_.sensor_silent_at_s + cfg_.sensor_silent_for_s;
}

void EmulatorNodes::rebootSensor(TimeUs downtime_us) {
  rebooting_ = true;
  reboot_until_ = now_us_ + std::max<TimeUs>(downtime_us, 1);
  delayed_count_ = 0;
}

bool EmulatorNodes::FaultyLink::send(const Frame& f) {
  EmulatorNodes& o = owner_;
  if (!sensor_) return o.inj_.valve_silent ? true : inner_.send(f);
  if (o.sensorSilent()) return true;  // swallowed: a silent node sends nothing at all
  Frame g = f;
  if ((f.id & 0x7FFu) == o.pdo_cob_) {
    if (o.inj_.drop_next > 0) {
      --o.inj_.drop_next;
      ++o.dropped_;
      return true;
    }
    const double p = std::max(o.cfg_.drop_pdo_prob, o.inj_.drop_prob);
    if (p > 0) {
      std::uniform_real_distribution<double> U(0.0, 1.0);
      if (U(o.rng_) < p) {
        ++o.dropped_;
        return true;
      }
    }
    if (o.inj_.pdo_len >= 0) g.len = static_cast<std::uint8_t>(std::min(o.inj_.pdo_len, 8));
    const int copies = o.inj_.pdo_duplicate ? 2 : 1;
    if (o.inj_.pdo_delay_us > 0) {
      for (int i = 0; i < copies && o.delayed_count_ < o.delayed_.size(); ++i) {
        o.delayed_[(o.delayed_head_ + o.delayed_count_) % o.delayed_.size()] = {g, o.now_us_ + o.inj_.pdo_delay_us};
        ++o.delayed_count_;
      }
      return true;
    }
    bool ok = inner_.send(g);
    if (copies == 2) inner_.send(g);
    return ok;
  }
  if ((f.id & 0x7FFu) == 0x700u + o.sensor_->nodeId() && o.inj_.heartbeat_len >= 0)
    g.len = static_cast<std::uint8_t>(std::min(o.inj_.heartbeat_len, 8));
  return inner_.send(g);
}

void EmulatorNodes::releaseDelayed(TimeUs now) {
  while (delayed_count_ > 0 && delayed_[delayed_head_].due <= now) {
    bus_.send(delayed_[delayed_head_].frame);
    delayed_head_ = (delayed_head_ + 1) % delayed_.size();
    --delayed_count_;
  }
}

void EmulatorNodes::updateValve(TimeUs now) {
  const bool sync_lost = valve_->sync().timedOut();
  const std::uint8_t master = masterId();
  const bool master_lost = master != 0 && valve_->heartbeatConsumer().timedOut(master);
  const bool ok = valve_->nmtState() == NmtState::Operational && !sync_lost && !master_lost;
  // The output goes to its error value (CiA 401: 0x6443/0x6444) and says so: an EMCY with the cause
  // and the communication bit of the error register 0x1001, until a fresh synchronous command (RPDO1
  // received since the last SYNC while Operational, with SYNC and the master's heartbeat present)
  // re-arms it - an SDO write to 0x6411:01 is stored but does not (docs/CANOPEN.md).
  // A commanded NMT state (Pre-operational, Stopped) applies the error value without an EMCY; a lost
  // SYNC or master heartbeat sends one (again if the cause changes).
  const std::uint16_t cause = master_lost ? canopen::kEmcyHeartbeat : sync_lost ? canopen::kEmcyCommunication : 0;
  if (!ok) {
    valve_error_ = true;
    if (cause != 0 && cause != valve_error_code_) {
      if (valve_error_code_ != 0) valve_->emcy().clear(valve_error_code_);
      valve_->emcy().report(cause);
      valve_error_code_ = cause;
    }
  } else if (valve_error_ && valve_->rpdo(1).syncsSinceReception() == 0) {
    valve_error_ = false;  // a fresh command
    if (valve_error_code_ != 0) valve_->emcy().clear(valve_error_code_);
    valve_error_code_ = 0;
  }
  const bool error_out = valve_error_ && error_mode_.get() != 0;
  const auto& sc = cfg_.scaling;
  const double lo = sc.command_zero_counts, hi = sc.command_zero_counts + sc.command_full_counts;
  const double u = sc.commandFromCounts(error_out ? std::clamp(static_cast<double>(error_value_.get()), lo, hi)
                                                  : static_cast<double>(command_.get()));
  if (u != u_held_) {
    u_held_ = u;
    valve_changed_us_ = now;
  }
}

void EmulatorNodes::onFrame(const Frame& f, TimeUs now) {
  now_us_ = now;
  releaseDelayed(now);
  const bool sync = (f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended();
  if (sync) {
    // Physics over the cycle that just ended, under the command held during it.
    ++syncs_;
    const double F = cfg_.payload_at_s >= 0 && time() >= cfg_.payload_at_s ? cfg_.payload_N : 0.0;
    plant_.step(u_held_, F);
    const double y = plant_.measure();
    const auto counts = cfg_.scaling.positionCounts(y);
    late_[syncs_ % late_.size()] = counts;
    const int lag = std::clamp(cfg_.late_pdo_cycles, 0, static_cast<int>(late_.size()) - 1);
    position_.set(syncs_ > static_cast<std::uint64_t>(lag) ? late_[(syncs_ - static_cast<std::uint64_t>(lag)) % late_.size()] : counts);
    pressure_.set(cfg_.scaling.pressureCounts(plant_.pressure_bar()));
  }
  if (!sensorSilent()) sensor_->onFrame(f, now);
  valve_->onFrame(f, now);
  // The valve latched the command of the last cycle at this SYNC: it holds until the next one.
  if (sync) updateValve(now);
}

void EmulatorNodes::advance(TimeUs now) {
  now_us_ = now;
  releaseDelayed(now);
  if (rebooting_ && now >= reboot_until_) {
    rebooting_ = false;
    // Power back: the node starts over (boot-up frame, Pre-operational, EDS defaults).
    sensor_->applyNmt(canopen::NmtCommand::ResetNode);
  }
  if (!rebooting_) sensor_->advance(now);
  valve_->advance(now);
}

TimeUs EmulatorNodes::nextDeadline() const {
  TimeUs next = std::min(rebooting_ ? reboot_until_ : sensor_->nextDeadline(), valve_->nextDeadline());
  if (delayed_count_ > 0) next = std::min(next, delayed_[delayed_head_].due);
  return next;
}

}  // namespace pamc::nodes
