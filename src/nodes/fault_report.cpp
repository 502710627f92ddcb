#include "nodes/fault_report.hpp"

#include <cstdio>

namespace pamc::nodes {

std::string describeFault(const ControllerNode& n, Fault f) {
  char b[512];
  switch (f) {
    case Fault::None: return "fault cleared: estimator and integrator restarted";
    case Fault::IdCollision:
      std::snprintf(b, sizeof b,
                    "fault: %s (frame on COB-ID 0x%03X from another node) -> valve to its safe value, EMCY 0x%04X sent",
                    toString(f), n.lastCollisionCob(), emcyCode(f));
      return b;
    case Fault::NoPosition:
      std::snprintf(
          b, sizeof b,
          "fault: no position within %g s of Operational: waiting for the sensor's (node %u) PDO on COB-ID 0x%03X; "
          "is the sensor Operational, its TPDO moved to another COB-ID, its mapping changed, or its transmission "
          "type asynchronous (not on SYNC)? -> valve to its safe value, EMCY 0x%04X sent",
          n.noPositionSeconds(), n.sensorId(), n.positionCob(), emcyCode(f));
      return b;
    default:
      std::snprintf(b, sizeof b, "fault: %s -> valve to its safe value, EMCY 0x%04X sent", toString(f), emcyCode(f));
      return b;
  }
}

void FaultReporter::step(const ControllerNode& n) {
  if (!range_said_ && n.rangeWatch().outside()) {
    range_said_ = true;
    if (out_) out_(n.rangeWatch().describe());
  }
  if (!distrust_said_ && n.rangeWatch().distrusted()) {
    distrust_said_ = true;
    if (out_) out_(n.rangeWatch().describeDistrust());
  }
  const Fault f = n.fault();
  if (f == last_) return;
  last_ = f;
  if (out_) out_(describeFault(n, f));
}

std::optional<std::string> runFailure(const ControllerNode& n) {
  if (n.faultCounters().positions > 0) return std::nullopt;
  char b[256];
  std::snprintf(b, sizeof b, "no position in the whole run: nothing came from the sensor (node %u) on COB-ID 0x%03X",
                n.sensorId(), n.positionCob());
  return std::string(b);
}

}  // namespace pamc::nodes
