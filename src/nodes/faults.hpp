// The controller node's faults, one table: each fault's text, its CiA 301 emergency error code and
// whether it is a warning (EMCY and counted, the loop runs on) or puts the valve in its safe state.
// Adding a fault is one enum value and one row (docs/CANOPEN.md, "Safe state").
#pragma once

#include <cstdint>

#include "canopen/emcy.hpp"

namespace pamc::nodes {

enum class Fault : std::uint8_t {
  None = 0,
  SensorHeartbeat = 1,  // no heartbeat from the sensor node
  PositionMissing = 2,  // no usable position PDO for more than 0x2021 cycles
  Estimator = 3,        // non-finite command or estimate, the UKF had to reset, or a set that does not configure
  BusError = 4,         // CAN controller error passive
  ValveHeartbeat = 5,   // no heartbeat from the valve node
  SyncLost = 6,         // SYNC consumer: no SYNC within 1.5 periods
  SensorState = 7,      // the sensor rebooted (boot-up) or is not Operational
  ValveState = 8,       // the valve rebooted, is stopped, or does not stay Operational
  ValvePdoMissing = 9,  // no pressure PDO from the valve for more than 0x2021 cycles
  CanOverrun = 10,      // frames lost: this node's transmit queue full, or a controller overflow
  BusOff = 11,          // CAN controller bus off (EMCY 0x8140 once it has restarted)
  IdCollision = 12,     // another node sends on this node's identifiers (same node-ID)
  SensorConflict = 13,  // two different positions in one cycle, three cycles running (two sensors)
  // Warnings: EMCY and counted, the loop runs on (the frame itself is discarded).
  PdoLength = 14,   // an RPDO with a wrong length (never decoded)
  SyncLength = 15,  // a SYNC with a wrong length (consumer)
  // Safety faults of the position's plausibility (0x2022).
  SensorStuck = 16,    // the position has not changed while the command moved by 0x2022:03 V
  PositionRange = 17,  // more than 0x2021 positions in a row outside the measuring range 0x2022:01
  // Warning: the slave is left stopped (the loop cannot start with it; a running loop meets ...State).
  SlaveBoot = 18,  // a slave's identity did not match, or it refused or lost its configuration at boot
  // Safety fault: the loop never started.
  NoPosition = 19,  // no position PDO within ControllerNodeConfig::no_position_s of entering Operational (or of the
                    // sensor's boot)
  // Safety fault of a node with several channels: it follows another channel into the safe state.
  OtherChannel = 20,  // its joint partner (or, with faults = all, any channel) is in its safe state
};
inline constexpr int kFaultCount = 21;

struct FaultInfo {
  Fault fault;
  const char* text;
  std::uint16_t emcy;  // CiA 301 emergency error code
  bool warning;        // true: EMCY and counted, the loop runs on
};

// Indexed by the enum's value (checked at compile time below).
inline constexpr FaultInfo kFaults[kFaultCount] = {
    {Fault::None, "none", 0x0000, false},
    {Fault::SensorHeartbeat, "sensor heartbeat lost", canopen::kEmcyHeartbeat, false},
    {Fault::PositionMissing, "position PDO missing", canopen::kEmcyRpdoTimeout, false},
    {Fault::Estimator, "estimator failure (non-finite or reset)", canopen::kEmcySoftware, false},
    {Fault::BusError, "CAN error passive", canopen::kEmcyErrorPassive, false},
    {Fault::ValveHeartbeat, "valve heartbeat lost", canopen::kEmcyHeartbeat, false},
    // No SYNC code in CiA 301: the generic communication code.
    {Fault::SyncLost, "SYNC lost", canopen::kEmcyCommunication, false},
    {Fault::SensorState, "sensor rebooted or not operational", canopen::kEmcyHeartbeat, false},
    {Fault::ValveState, "valve rebooted, stopped or not operational", canopen::kEmcyHeartbeat, false},
    {Fault::ValvePdoMissing, "valve PDO missing", canopen::kEmcyRpdoTimeout, false},
    {Fault::CanOverrun, "CAN overrun (frames lost)", canopen::kEmcyCanOverrun, false},
    // Sent once the CAN controller has restarted.
    {Fault::BusOff, "CAN bus off", canopen::kEmcyBusOffRecovered, false},
    {Fault::IdCollision, "another node uses this node-ID", canopen::kEmcyCanIdCollision, false},
    {Fault::SensorConflict, "two sources of the position PDO", canopen::kEmcyCanIdCollision, false},
    {Fault::PdoLength, "PDO with wrong length discarded", canopen::kEmcyPdoLength, true},
    {Fault::SyncLength, "SYNC with wrong length discarded", canopen::kEmcySyncLength, true},
    {Fault::SensorStuck, "sensor stuck (position unchanged while the command moved)", canopen::kEmcySensor, false},
    {Fault::PositionRange, "position outside the sensor's measuring range", canopen::kEmcySensorRange, false},
    // CiA 301 has no code for a slave's configuration: "data set" (software, 0x63xx).
    {Fault::SlaveBoot, "slave boot failed (identity or configuration)", canopen::kEmcyDataSet, true},
    // An RPDO that never came is an RPDO timeout too; the first byte of the EMCY (19) tells it apart.
    {Fault::NoPosition, "no position since Operational", canopen::kEmcyRpdoTimeout, false},
    // The EMCY's second byte is the channel whose fault it follows (1-based).
    {Fault::OtherChannel, "another channel of its joint is in its safe state", canopen::kEmcyDeviceSpecific, false},
};

constexpr bool faultTableInOrder() {
  for (int i = 0; i < kFaultCount; ++i)
    if (static_cast<int>(kFaults[i].fault) != i) return false;
  return true;
}
static_assert(faultTableInOrder(), "kFaults must list every fault in the enum's order");

constexpr const FaultInfo& faultInfo(Fault f) {
  return kFaults[static_cast<int>(f) < kFaultCount ? static_cast<int>(f) : 0];
}
constexpr const char* toString(Fault f) { return faultInfo(f).text; }
constexpr std::uint16_t emcyCode(Fault f) { return faultInfo(f).emcy; }
constexpr bool isWarning(Fault f) { return faultInfo(f).warning; }

// Bit masks over the faults (bit per enum value).
constexpr std::uint32_t faultBit(Fault f) { return 1u << static_cast<unsigned>(f); }
constexpr std::uint32_t warningMask() {
  std::uint32_t m = 0;
  for (const auto& f : kFaults)
    if (f.warning) m |= faultBit(f.fault);
  return m;
}

}  // namespace pamc::nodes
