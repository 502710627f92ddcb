#include "nodes/emulator_node.hpp"

#include <algorithm>
#include <cmath>

namespace pamc::nodes {

using canopen::Frame;
using canopen::TimeUs;

EmulatorNodes::EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport)
    : cfg_(cfg), sensor_link_(*this, transport), plant_(cfg.plant), rng_(cfg.seed) {
  sensor_ = canopen::Node::fromEds(cfg.sensor_eds, sensor_link_);
  valve_ = canopen::Node::fromEds(cfg.valve_eds, transport);
  position_ = sensor_->od().ref<std::int32_t>(0x6004, 0);
  pressure_ = valve_->od().ref<std::int16_t>(0x6401, 1);
  command_ = valve_->od().ref<std::int16_t>(0x6411, 1);
  sync_cob_ = sensor_->od().ref<std::uint32_t>(0x1005, 0).get() & 0x7FFu;
  pdo_cob_ = sensor_->od().ref<std::uint32_t>(0x1800, 1).get() & 0x7FFu;
  // The valve holds its command at 0 V (vented) until the controller sends one.
  plant_.reset(-5.0, 0.0);
  position_.set(static_cast<std::int32_t>(std::lround(plant_.position() * 1000.0)));
}

void EmulatorNodes::start(TimeUs now) {
  sensor_->start(now);
  valve_->start(now);
}

bool EmulatorNodes::sensorSilent() const {
  const double t = time();
  return cfg_.sensor_silent_at_s >= 0 && t >= cfg_.sensor_silent_at_s &&
         t < cfg_.sensor_silent_at_s + cfg_.sensor_silent_for_s;
}

bool EmulatorNodes::FaultyLink::send(const Frame& f) {
  if (owner_.sensorSilent()) return true;  // swallowed: a silent node sends nothing at all
  if ((f.id & 0x7FFu) == owner_.pdo_cob_ && owner_.cfg_.drop_pdo_prob > 0) {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    if (U(owner_.rng_) < owner_.cfg_.drop_pdo_prob) {
      ++owner_.dropped_;
      return true;
    }
  }
  return inner_.send(f);
}

void EmulatorNodes::onFrame(const Frame& f, TimeUs now) {
  if ((f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended()) {
    // Physics over the cycle that just ended, under the command held during it.
    ++syncs_;
    const double F = cfg_.payload_at_s >= 0 && time() >= cfg_.payload_at_s ? cfg_.payload_N : 0.0;
    plant_.step(u_held_, F);
    const double y = plant_.measure();
    const auto counts = static_cast<std::int32_t>(std::lround(std::clamp(y, -2.0e6, 2.0e6) * 1000.0));
    late_[syncs_ % late_.size()] = counts;
    const int lag = std::clamp(cfg_.late_pdo_cycles, 0, static_cast<int>(late_.size()) - 1);
    position_.set(syncs_ > static_cast<std::uint64_t>(lag) ? late_[(syncs_ - static_cast<std::uint64_t>(lag)) % late_.size()] : counts);
    pressure_.set(static_cast<std::int16_t>(std::lround(std::clamp(plant_.pressure_bar(), 0.0, 10.0) * 32767.0 / 10.0)));
  }
  if (!sensorSilent()) sensor_->onFrame(f, now);
  valve_->onFrame(f, now);
  if ((f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended()) {
    // The valve latched the command of the last cycle at this SYNC: it holds until the next one.
    u_held_ = command_.get() * 10.0 / 32767.0 - 5.0;
  }
}

void EmulatorNodes::advance(TimeUs now) {
  sensor_->advance(now);
  valve_->advance(now);
}

TimeUs EmulatorNodes::nextDeadline() const { return std::min(sensor_->nextDeadline(), valve_->nextDeadline()); }

}  // namespace pamc::nodes
