#include "nodes/valve_driver.hpp"

namespace pamc::nodes {

using canopen::TimeUs;

ValveDriver::ValveDriver(canopen::Node& node, canopen::NmtMaster& master, std::uint8_t id, const pd::Scaling& scaling,
                         bool feedback, std::uint16_t error_value_index, std::uint8_t error_value_sub,
                         unsigned feedback_rpdo, std::uint16_t command_object, std::uint16_t pressure_object)
    : node_(node),
      master_(master),
      id_(id),
      scaling_(scaling),
      feedback_(feedback),
      error_value_index_(error_value_index),
      error_value_sub_(error_value_sub),
      feedback_rpdo_(feedback_rpdo),
      command_object_(command_object),
      pressure_object_(pressure_object) {
  master_.addSlave(id_);
}

void ValveDriver::errorValueAtBoot(std::function<double()> safe_u) {
  safe_u_ = safe_u;
  if (error_value_index_ == 0) return;
  // CiA 401: the valve outputs 0x6444:n (INTEGER32) on a communication error.
  master_.addConfig(
      id_, {canopen::SlaveBoot::Write{error_value_index_, error_value_sub_, 4, [this, safe_u = std::move(safe_u)] {
                                        return static_cast<std::uint32_t>(
                                            static_cast<std::int32_t>(scaling_.commandCounts(safe_u())));
                                      }}});
}

void ValveDriver::pushErrorValue(double safe_u) noexcept {
  // CiA 401: the valve outputs 0x6444:n on a communication error; make it the controller's safe value.
  const std::int32_t v = scaling_.commandCounts(safe_u);
  auto& sdo = node_.sdoClient();
  // Nothing is written to a slave before its boot has checked its identity (0x1000, 0x1018 against
  // 0x1F84-0x1F88): until then, or after a failed boot, the value waits.
  if (sdo.busy() || !master_.configured(id_)) return;
  push_ = false;
  if (error_value_index_ == 0) return;
  sdo.downloadValue<std::int32_t>(id_, error_value_index_, error_value_sub_, v,
                                  [this](std::uint32_t code, const std::uint8_t*, std::size_t) {
                                    if (code != canopen::kSdoOk) ++sdo_errors_;
                                  });
}

// Kept alive and running, the valve was not configured by this boot: its error value goes out now -
// the safe value may have changed since it was configured - unless the SDO client is busy (then from
// the cycle). Back after a boot-up, a valve the master does not boot gets it from the cycle.
void ValveDriver::onEvent(canopen::SlaveEvent ev, TimeUs, FaultSupervisor& f, bool active) noexcept {
  using canopen::SlaveEvent;
  switch (ev) {
    case SlaveEvent::Configured: break;
    case SlaveEvent::KeptAlive:
      errorValueDue();
      if (safe_u_) pushErrorValue(safe_u_());
      break;
    case SlaveEvent::BootFailed: f.raise(Fault::SlaveBoot, id_); break;
    case SlaveEvent::Lost: f.raise(Fault::ValveHeartbeat, id_); break;
    case SlaveEvent::BootUp:
      if (!master_.boots(id_)) errorValueDue();
      if (active) f.raise(Fault::ValveState, id_);
      break;
    case SlaveEvent::LeftOperational:
    case SlaveEvent::Stopped:
      if (active) f.raise(Fault::ValveState, id_);
      break;
  }
}

void ValveDriver::supervise(FaultSupervisor& f, const DriverCycle& c) noexcept {
  const TimeUs now = c.now;
  const bool active = c.active;
  const std::uint64_t cycle = c.cycle;
  const unsigned missing_limit = c.ps->missing_limit;
  if (!active) return;
  if (master_.timedOut(id_)) f.raise(Fault::ValveHeartbeat, id_);
  if (holdReasons() != 0 || !master_.configured(id_)) return;
  if (master_.down(id_, now)) f.raise(Fault::ValveState, id_);
  if (feedback_ && !master_.starting(id_, now) && cycle > missing_limit &&
      feedback_pdo_->syncsSinceReception() > missing_limit)
    f.raise(Fault::ValvePdoMissing);
}

}  // namespace pamc::nodes
