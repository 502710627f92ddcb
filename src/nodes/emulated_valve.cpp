#include "nodes/emulated_valve.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace pamc::nodes {

using canopen::Frame;
using canopen::NmtState;
using canopen::TimeUs;

EmulatedValve::EmulatedValve(const EmulatorConfig& cfg, canopen::Transport& bus, const Injection& inj, std::uint8_t id,
                             std::size_t outputs)
    : cfg_(cfg), bus_(bus), inj_(inj) {
  node_ = canopen::Node::fromEds(cfg.valve_eds, *this, id);
  if (outputs < 1 || outputs > out_.size())
    throw std::invalid_argument("emulator: a valve module of " + std::to_string(outputs) + " outputs (1..8)");
  auto& od = node_->od();
  n_ = outputs;
  for (std::size_t c = 0; c < n_; ++c) {
    const auto cs = static_cast<std::uint8_t>(cfg.command_sub + c),
               ps = static_cast<std::uint8_t>(cfg.pressure_sub + c);
    out_[c].pressure = od.ref<std::int16_t>(cfg.pressure_index, ps);
    out_[c].command = od.ref<std::int16_t>(cfg.command_index, cs);
    out_[c].error_mode = od.ref<std::uint8_t>(0x6443, cs);
    out_[c].error_value = od.ref<std::int32_t>(0x6444, cs);
  }
  master_hb_ = od.find(0x1016, 1);
  monitorSync();
  node_->onReset([this](canopen::NmtCommand, TimeUs) { monitorSync(); });
  node_->onStateChange([this](NmtState, NmtState, TimeUs now) { update(now); });
  node_->onSyncTimeout([this](TimeUs now) { update(now); });
  node_->onHeartbeat([this](std::uint8_t id, canopen::HeartbeatEvent ev, NmtState, TimeUs now) {
    if (id == masterId() && ev == canopen::HeartbeatEvent::Timeout) update(now);
  });
}

// The valve monitors the SYNC with the emulator's period (1.5 periods without one: error value).
void EmulatedValve::monitorSync() {
  const auto period_us = static_cast<std::uint32_t>(std::lround(cfg_.plant.Ts * 1e6));
  if (auto* e = node_->od().find(0x1006, 0)) e->set<std::uint32_t>(period_us);
}

// The master whose heartbeat the valve watches: 0x1016:01, as a master may have written it.
std::uint8_t EmulatedValve::masterId() const {
  return master_hb_ ? static_cast<std::uint8_t>((master_hb_->asUnsigned() >> 16) & 0x7F) : 0;
}

bool EmulatedValve::send(const Frame& f) { return inj_.valve_silent ? true : bus_.send(f); }

void EmulatedValve::reportPressure(double bar, std::size_t c) {
  out_[c].pressure.set(cfg_.scaling.pressureCounts(bar));
}

// The output goes to its error value (CiA 401: 0x6443/0x6444) and says so: an EMCY with the cause
// and the communication bit of the error register 0x1001, until a fresh synchronous command (RPDO1
// received since the last SYNC while Operational, with SYNC and the master's heartbeat present)
// re-arms it - an SDO write to 0x6411:01 is stored but does not (docs/CANOPEN.md).
// A commanded NMT state (Pre-operational, Stopped) applies the error value without an EMCY; a lost
// SYNC or master heartbeat sends one (again if the cause changes).
void EmulatedValve::update(TimeUs now) {
  const bool sync_lost = node_->sync().timedOut();
  const std::uint8_t master = masterId();
  const bool master_lost = master != 0 && node_->heartbeatConsumer().timedOut(master);
  const bool ok = node_->nmtState() == NmtState::Operational && !sync_lost && !master_lost;
  const std::uint16_t cause = master_lost ? canopen::kEmcyHeartbeat : sync_lost ? canopen::kEmcyCommunication : 0;
  if (!ok)
    enterError(cause);
  else if (error_ && node_->rpdo(1).syncsSinceReception() == 0)
    leaveError();  // a fresh command
  for (std::size_t c = 0; c < n_; ++c) apply(out_[c], now);
}

// What one output puts out: its command, or its error value in the error state (with error mode 1).
void EmulatedValve::apply(Output& o, TimeUs now) {
  const bool error_out = error_ && o.error_mode.get() != 0;
  const auto& sc = cfg_.scaling;
  const double lo = sc.command_zero_counts, hi = sc.command_zero_counts + sc.command_full_counts;
  const double u = sc.commandFromCounts(error_out ? std::clamp(static_cast<double>(o.error_value.get()), lo, hi)
                                                  : static_cast<double>(o.command.get()));
  if (u != o.u_held) {
    o.u_held = u;
    o.changed_us = now;
  }
}

void EmulatedValve::enterError(std::uint16_t cause) {
  error_ = true;
  if (cause == 0 || cause == error_code_) return;
  if (error_code_ != 0) node_->emcy().clear(error_code_);
  node_->emcy().report(cause);
  error_code_ = cause;
}

void EmulatedValve::leaveError() {
  error_ = false;
  if (error_code_ != 0) node_->emcy().clear(error_code_);
  error_code_ = 0;
}

}  // namespace pamc::nodes
