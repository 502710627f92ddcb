// A channel's valve output as the controller node sees it - a driver in the sense of Lely's coapp
// Driver (nodes/driver.hpp): its boot steps, the command it gets in the TPDO after each cycle (channel
// 1: 0x3002 in TPDO1, in the valve's counts; ChannelConfig says which for the others), its error
// value (CiA 401 0x6444:n, the controller's safe value: its configuration in every boot of the valve,
// after the identity check and the concise DCF, and written again when the safe value changes), the
// supervision of its feedback PDO, heartbeat and state, and the reasons to hold it in Pre-operational.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <optional>

#include "canopen/nmt_master.hpp"
#include "canopen/node.hpp"
#include "nodes/driver.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

class ValveDriver final : public Driver {
 public:
  // Reasons the valve is held in Pre-operational, where it outputs its error value.
  enum : std::uint8_t { kHoldSync = 1, kHoldCollision = 2, kHoldSelf = 4 };

  // error_value_index 0: the valve has no error value to write. The command goes into command_object,
  // the pressure comes into pressure_object in the controller's RPDO feedback_rpdo.
  ValveDriver(canopen::Node& node, canopen::NmtMaster& master, std::uint8_t id, const pd::Scaling& scaling,
              bool feedback, std::uint16_t error_value_index, std::uint8_t error_value_sub, unsigned feedback_rpdo = 2,
              std::uint16_t command_object = 0x3002, std::uint16_t pressure_object = 0x3001);
  void bind() {
    cmd_ = node_.od().ref<std::int16_t>(command_object_, 0);
    pressure_ = node_.od().ref<std::int16_t>(pressure_object_, 0);
    if (feedback_) feedback_pdo_ = &node_.rpdo(feedback_rpdo_);
  }
  const char* role() const noexcept override { return "valve"; }
  void onOperational(canopen::TimeUs) noexcept override {}
  void onEvent(canopen::SlaveEvent ev, canopen::TimeUs now, FaultSupervisor& f, bool active) noexcept override;

  void command(double u) noexcept { cmd_.set(scaling_.commandCounts(u)); }  // relative volts
  void zero() noexcept { cmd_.set(0); }
  // The driver's configuration in the valve's boot (NmtMaster::addConfig): the error value, safe_u()
  // in relative volts as the write goes out - after the identity check and the concise DCF, before
  // the start.
  void errorValueAtBoot(std::function<double()> safe_u);
  // Between boots the error value follows the safe value: written when the SDO client is free and the
  // valve is configured (NmtMaster::configured), never before.
  void errorValueDue() noexcept { push_ = true; }
  bool errorValuePending() const noexcept { return push_; }
  void pushErrorValue(double safe_u) noexcept;
  void supervise(FaultSupervisor& f, const DriverCycle& c) noexcept override;

  void hold(std::uint8_t reason) noexcept { master_.hold(id_, reason); }
  void release(std::uint8_t reason, canopen::TimeUs now) noexcept { master_.release(id_, reason, now); }
  std::uint8_t holdReasons() const noexcept { return master_.holdReasons(id_); }

  // The pressure its feedback PDO brought (RPDO2 into 0x3001) [bar]; NaN without a feedback PDO.
  double pressureBar() const noexcept { return feedback_ ? scaling_.bar(pressure_.get()) : NAN; }
  std::uint8_t id() const noexcept override { return id_; }
  std::uint64_t sdoErrors() const noexcept { return sdo_errors_; }

 private:
  canopen::Node& node_;
  canopen::NmtMaster& master_;
  std::uint8_t id_;
  pd::Scaling scaling_;
  bool feedback_;  // the valve sends its pressure; its absence is a fault
  std::uint16_t error_value_index_;
  std::uint8_t error_value_sub_;
  unsigned feedback_rpdo_;
  std::uint16_t command_object_, pressure_object_;
  std::function<double()> safe_u_;  // the safe value, for the error value written outside the boot
  canopen::Ref<std::int16_t> cmd_{nullptr};
  canopen::Ref<std::int16_t> pressure_{nullptr};
  const canopen::Rpdo* feedback_pdo_ = nullptr;  // the pressure's RPDO where the valve sends one (bind())
  bool push_ = false;
  std::uint64_t sdo_errors_ = 0;  // writing the error value failed
};

}  // namespace pamc::nodes
