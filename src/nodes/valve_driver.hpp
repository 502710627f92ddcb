// The valve as the controller node sees it - a driver in the sense of Lely's coapp Driver: its boot
// steps, the command it gets in the TPDO after each cycle (0x3002, in the valve's counts), its error
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
#include "nodes/fault_supervisor.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

class ValveDriver {
 public:
  // Reasons the valve is held in Pre-operational, where it outputs its error value.
  enum : std::uint8_t { kHoldSync = 1, kHoldCollision = 2, kHoldSelf = 4 };

  // error_value_index 0: the valve has no error value to write.
  ValveDriver(canopen::Node& node, canopen::NmtMaster& master, std::uint8_t id, const pd::Scaling& scaling,
              bool feedback, std::uint16_t error_value_index, std::uint8_t error_value_sub);
  void bind() {
    cmd_ = node_.od().ref<std::int16_t>(0x3002, 0);
    pressure_ = node_.od().ref<std::int16_t>(0x3001, 0);
  }

  void command(double u) noexcept { cmd_.set(scaling_.commandCounts(u)); }  // relative volts
  void zero() noexcept { cmd_.set(0); }
  // The driver's configuration in the valve's boot (NmtMaster::setConfig): the error value, safe_u()
  // in relative volts as the write goes out - after the identity check and the concise DCF, before
  // the start.
  void errorValueAtBoot(std::function<double()> safe_u);
  // Between boots the error value follows the safe value: written when the SDO client is free and the
  // valve is configured (NmtMaster::configured), never before.
  void errorValueDue() noexcept { push_ = true; }
  bool errorValuePending() const noexcept { return push_; }
  void pushErrorValue(double safe_u) noexcept;
  void supervise(FaultSupervisor& f, canopen::TimeUs now, bool active, std::uint64_t cycle, unsigned missing_limit) noexcept;

  void hold(std::uint8_t reason) noexcept { master_.hold(id_, reason); }
  void release(std::uint8_t reason, canopen::TimeUs now) noexcept { master_.release(id_, reason, now); }
  std::uint8_t holdReasons() const noexcept { return master_.holdReasons(id_); }

  // The pressure its feedback PDO brought (RPDO2 into 0x3001) [bar]; NaN without a feedback PDO.
  double pressureBar() const noexcept { return feedback_ ? scaling_.bar(pressure_.get()) : NAN; }
  std::uint8_t id() const noexcept { return id_; }
  std::uint64_t sdoErrors() const noexcept { return sdo_errors_; }

 private:
  canopen::Node& node_;
  canopen::NmtMaster& master_;
  std::uint8_t id_;
  pd::Scaling scaling_;
  bool feedback_;  // the valve sends its pressure; its absence is a fault
  std::uint16_t error_value_index_;
  std::uint8_t error_value_sub_;
  canopen::Ref<std::int16_t> cmd_{nullptr};
  canopen::Ref<std::int16_t> pressure_{nullptr};
  bool push_ = false;
  std::uint64_t sdo_errors_ = 0;  // writing the error value failed
};

}  // namespace pamc::nodes
