#include "nodes/emulated_sensor.hpp"

#include <algorithm>

namespace pamc::nodes {

using canopen::Frame;
using canopen::TimeUs;

void DelayLine::push(const Frame& f, TimeUs due) {
  if (count_ == frames_.size()) return;
  frames_[(head_ + count_) % frames_.size()] = {f, due};
  ++count_;
}

void DelayLine::release(canopen::Transport& to, TimeUs now) {
  while (count_ > 0 && frames_[head_].due <= now) {
    to.send(frames_[head_].frame);
    head_ = (head_ + 1) % frames_.size();
    --count_;
  }
}

EmulatedSensor::EmulatedSensor(const EmulatorConfig& cfg, canopen::Transport& bus, Injection& inj, std::uint8_t id)
    : cfg_(cfg), bus_(bus), inj_(inj), rng_(cfg.seed) {
  node_ = canopen::Node::fromEds(cfg.sensor_eds, *this, id);
  position_ = node_->od().ref<std::int32_t>(cfg.position_index, cfg.position_sub);
  pdo_cob_ = node_->od().ref<std::uint32_t>(0x1800, 1).get() & 0x7FFu;
}

void EmulatedSensor::start(TimeUs now) {
  now_us_ = now;
  node_->start(now);
}

void EmulatedSensor::measured(std::uint64_t k, double t, std::int32_t counts) {
  t_ = t;
  late_[k % late_.size()] = counts;
  const int lag = std::clamp(cfg_.late_pdo_cycles, 0, static_cast<int>(late_.size()) - 1);
  const auto lag_k = static_cast<std::uint64_t>(lag);
  position_.set(k > lag_k ? late_[(k - lag_k) % late_.size()] : counts);
}

bool EmulatedSensor::silent() const {
  if (inj_.sensor_silent || rebooting_) return true;
  return cfg_.sensor_silent_at_s >= 0 && t_ >= cfg_.sensor_silent_at_s &&
         t_ < cfg_.sensor_silent_at_s + cfg_.sensor_silent_for_s;
}

void EmulatedSensor::reboot(TimeUs downtime_us) {
  rebooting_ = true;
  reboot_until_ = now_us_ + std::max<TimeUs>(downtime_us, 1);
  delayed_.clear();
}

void EmulatedSensor::tick(TimeUs now) {
  now_us_ = now;
  delayed_.release(bus_, now);
}

void EmulatedSensor::onFrame(const Frame& f, TimeUs now) {
  if (!silent()) node_->onFrame(f, now);
}

void EmulatedSensor::advance(TimeUs now) {
  if (rebooting_ && now >= reboot_until_) {
    rebooting_ = false;
    // Power back: the node starts over (boot-up frame, Pre-operational, EDS defaults).
    node_->applyNmt(canopen::NmtCommand::ResetNode);
  }
  if (!rebooting_) node_->advance(now);
}

TimeUs EmulatedSensor::nextDeadline() const {
  return std::min(rebooting_ ? reboot_until_ : node_->nextDeadline(), delayed_.nextDue());
}

bool EmulatedSensor::send(const Frame& f) {
  if (silent()) return true;  // swallowed: a silent node sends nothing at all
  if ((f.id & 0x7FFu) == pdo_cob_) return dropPosition() || sendPosition(f);
  Frame g = f;
  if ((f.id & 0x7FFu) == 0x700u + node_->nodeId() && inj_.heartbeat_len >= 0)
    g.len = static_cast<std::uint8_t>(std::min(inj_.heartbeat_len, 8));
  return bus_.send(g);
}

// Whether this position PDO is lost: the rest of an injected burst, or at random.
bool EmulatedSensor::dropPosition() {
  if (inj_.drop_next > 0) {
    --inj_.drop_next;
    ++dropped_;
    return true;
  }
  const double p = std::max(cfg_.drop_pdo_prob, inj_.drop_prob);
  if (p > 0) {
    std::uniform_real_distribution<double> U(0.0, 1.0);
    if (U(rng_) < p) {
      ++dropped_;
      return true;
    }
  }
  return false;
}

// A position PDO that goes out: with the injected length, once or twice, now or after the delay.
bool EmulatedSensor::sendPosition(Frame g) {
  if (inj_.pdo_len >= 0) g.len = static_cast<std::uint8_t>(std::min(inj_.pdo_len, 8));
  const int copies = inj_.pdo_duplicate ? 2 : 1;
  if (inj_.pdo_delay_us > 0) {
    for (int i = 0; i < copies; ++i) delayed_.push(g, now_us_ + inj_.pdo_delay_us);
    return true;
  }
  const bool ok = bus_.send(g);
  if (copies == 2) bus_.send(g);
  return ok;
}

}  // namespace pamc::nodes
