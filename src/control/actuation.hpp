// What the actuator chain fixes, written once: the valve's command range and the bus delay. Every
// other place (controllers, the nodes' process data, the lockstep simulation) derives from these.
#pragma once

namespace pamc::control {

// The proportional valve takes 0-10 V; the controllers' command u is relative to its mid-range
// (valve voltage = kValveMid_V + u), so u spans [kCommandMin, kCommandMax].
inline constexpr double kValveFullScale_V = 10.0;
inline constexpr double kValveMid_V = 5.0;
inline constexpr double kCommandMin = -kValveMid_V;  // 0 V at the valve: vented
inline constexpr double kCommandMax = kValveFullScale_V - kValveMid_V;

// Cycles between issuing a command and the first measurement that reflects it, beyond the one sample
// of any sampled loop: 2 on the CANopen bus - the valve applies a synchronous RPDO at the next SYNC,
// and the controller latches the position (sent after the SYNC at which it was sampled) at the SYNC
// after that.
inline constexpr int kBusDelayCycles = 2;

}  // namespace pamc::control
