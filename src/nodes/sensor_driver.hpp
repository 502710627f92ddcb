// A channel's position input as the controller node sees it - a driver in the sense of Lely's coapp
// Driver (nodes/driver.hpp): its boot steps (the measuring step read from a CiA 406 device), the
// position PDO latched at each SYNC (channel 1: RPDO1 into 0x3000; ChannelConfig says which for the
// others) and its supervision - missing, never come since Operational, two sources, out of the
// measuring range, stuck while the command moves, the sensor's heartbeat and state - and its scaling.
#pragma once

#include <atomic>
#include <cstdint>
#include <optional>

#include "canopen/nmt_master.hpp"
#include "canopen/node.hpp"
#include "nodes/driver.hpp"
#include "nodes/position_sample.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

class SensorDriver final : public Driver {
 public:
  // The position latched at a SYNC.
  struct Sample {
    std::int32_t raw = 0;
    double y = 0.0;       // [mm]
    double y_ctrl = 0.0;  // what the controller gets: y, or NaN outside the measuring range
    bool fresh = false;   // it arrived in the last cycle
    bool in_range = false;
    bool usable() const noexcept { return fresh && in_range; }
    PositionSample forLoop() const noexcept { return PositionSample{y, y_ctrl, usable()}; }
  };

  // rpdo: the controller's RPDO bringing the position into `object` (its entry :00).
  SensorDriver(canopen::Node& node, canopen::NmtMaster& master, std::uint8_t id, const pd::Scaling& scaling,
               double no_position_s, unsigned rpdo = 1, std::uint16_t object = 0x3000);
  // A boot step of its own: the measuring step read from the device (CiA 406 0x6005:01), after the
  // identity check and before the configuration the master's dictionary holds.
  void readStepAtBoot();
  // Its position object and PDO in the node (throws where the dictionary has neither).
  void bind() {
    position_ = node_.od().ref<std::int32_t>(object_, 0);
    pdo_ = &node_.rpdo(rpdo_);
  }
  const char* role() const noexcept override { return "sensor"; }
  void onOperational(canopen::TimeUs now) noexcept override;
  void onEvent(canopen::SlaveEvent ev, canopen::TimeUs now, FaultSupervisor& f, bool active) noexcept override;
  // Its boot finished: the time for a first position runs from here (a boot may take a while - a
  // keep-alive check, a slow heartbeat - and is supervised by the master itself).
  void onBooted(canopen::TimeUs now) noexcept {
    if (operational_at_ != canopen::kNever) operational_at_ = now;
  }
  void onLeftOperational() noexcept { operational_at_ = canopen::kNever; }

  // The cycle: latch, plausibility (u: the command in effect), supervision.
  Sample latch(const ParameterSet& ps) const noexcept;
  void checkPlausibility(const Sample& s, double u) noexcept;
  void supervise(FaultSupervisor& f, const DriverCycle& c) noexcept override;

  std::uint8_t id() const noexcept override { return id_; }
  const pd::Scaling& scaling() const noexcept { return scaling_; }
  std::uint32_t cob() const noexcept { return cob_pub_.load(std::memory_order_relaxed); }  // any thread
  double noPositionSeconds() const noexcept { return no_position_s_; }
  std::uint64_t positions() const noexcept { return positions_; }
  std::uint64_t samplesMissing() const noexcept { return samples_missing_; }

 private:
  canopen::Node& node_;
  canopen::NmtMaster& master_;
  std::uint8_t id_;
  unsigned rpdo_;
  std::uint16_t object_;
  pd::Scaling scaling_;  // the step may be read at the sensor's boot, before it starts
  double no_position_s_;
  canopen::Ref<std::int32_t> position_{nullptr};
  const canopen::Rpdo* pdo_ = nullptr;                // the position's RPDO (bind())
  canopen::TimeUs operational_at_ = canopen::kNever;  // the node entered Operational (kNever: it is not)
  int conflict_run_ = 0;
  // Plausibility: positions outside the range in a row; the run of identical positions and the
  // command's span since it began.
  unsigned range_run_ = 0;
  bool have_raw_ = false;
  std::int32_t raw_last_ = 0;
  unsigned same_run_ = 0;
  double run_u_min_ = 0.0, run_u_max_ = 0.0;
  std::uint64_t positions_ = 0;        // usable positions latched
  std::uint64_t samples_missing_ = 0;  // cycles after activation without one
  std::atomic<std::uint32_t> cob_pub_{0};
};

}  // namespace pamc::nodes
