// The one interface every slave driver of the controller node sits behind - as Lely's master calls
// each of its drivers: boot (the steps a driver adds to the slave's boot), the node entering
// Operational, the slave's NMT events (configured, kept alive, boot failed, lost, back, left
// Operational), and in each SYNC cycle the supervision that raises the faults of its channel. A
// channel has one input driver (its position) and one output driver (its valve); one slave may serve
// several channels, each with a driver of its own over the slave's objects for that channel.
#pragma once

#include <cstdint>

#include "canopen/nmt_master.hpp"
#include "nodes/controller_parameters.hpp"
#include "nodes/fault_supervisor.hpp"

namespace pamc::nodes {

// What a driver's supervision sees of the cycle.
struct DriverCycle {
  canopen::TimeUs now = 0;
  bool active = false;      // the channel's loop runs (a usable position was seen)
  bool usable = false;      // this cycle's position is fresh and plausible
  std::uint64_t cycle = 0;  // cycles since activation
  const ParameterSet* ps = nullptr;
  double Ts = 1e-3;
};

class Driver {
 public:
  virtual ~Driver() = default;
  virtual const char* role() const noexcept = 0;  // "sensor", "valve": the boot reports name it
  virtual std::uint8_t id() const noexcept = 0;   // the slave's node-ID
  virtual void onOperational(canopen::TimeUs now) noexcept = 0;
  // The slave's NMT events (nmt_master.hpp); active: the channel's loop runs.
  virtual void onEvent(canopen::SlaveEvent ev, canopen::TimeUs now, FaultSupervisor& f, bool active) noexcept = 0;
  virtual void supervise(FaultSupervisor& f, const DriverCycle& c) noexcept = 0;
};

}  // namespace pamc::nodes
