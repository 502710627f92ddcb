// What the numbers in the process data mean, written once: the position sensor's counts (CiA 406),
// the valve's analogue output and pressure input (CiA 401), and the offset between the controller's
// command u (volts relative to the valve's mid-range) and the valve's 0-10 V.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "control/actuation.hpp"

namespace pamc::nodes::pd {

inline constexpr double kPositionStep_mm = 0.001;                        // 0x6004 position value: counts of 1 um
inline constexpr double kAnalogFullScaleCounts = 32767;                  // 0x6411 / 0x6401: 0..32767 = 0..full scale
inline constexpr double kValveFullScale_V = control::kValveFullScale_V;  // 0x6411:01 setpoint, 0..10 V
inline constexpr double kValveMid_V = control::kValveMid_V;  // u = 0 is the valve's mid-range: volts = 5 V + u
inline constexpr double kPressureFullScale_bar = 10.0;       // 0x6401:01 pressure feedback, 0..10 bar
inline constexpr double kCommandMin = control::kCommandMin;  // u of 0 V at the valve
inline constexpr double kCommandMax = control::kCommandMax;

constexpr double valveVolts(double u) { return u + kValveMid_V; }
constexpr double commandFromVolts(double volts) { return volts - kValveMid_V; }

// Command u [V relative to mid-range] <-> the valve's setpoint counts (clamped to 0..10 V).
inline std::int16_t commandToCounts(double u) {
  const double v = std::clamp(valveVolts(u), 0.0, kValveFullScale_V);
  return static_cast<std::int16_t>(std::lround(v * kAnalogFullScaleCounts / kValveFullScale_V));
}
constexpr double countsToCommand(double counts) {
  return commandFromVolts(counts * kValveFullScale_V / kAnalogFullScaleCounts);
}

// Position [mm] <-> sensor counts.
constexpr double countsToMm(double counts) { return counts * kPositionStep_mm; }
inline std::int32_t mmToCounts(double y_mm) {
  return static_cast<std::int32_t>(std::lround(std::clamp(y_mm, -2.0e6, 2.0e6) / kPositionStep_mm));
}

// Pressure [bar] <-> the valve's feedback counts (clamped to 0..10 bar).
inline std::int16_t barToCounts(double bar) {
  return static_cast<std::int16_t>(
      std::lround(std::clamp(bar, 0.0, kPressureFullScale_bar) * kAnalogFullScaleCounts / kPressureFullScale_bar));
}
constexpr double countsToBar(double counts) { return counts * kPressureFullScale_bar / kAnalogFullScaleCounts; }

// The same conversions for slaves that count otherwise (a rig file's position step and valve scaling);
// the defaults are the constants above.
struct Scaling {
  double position_step_mm = kPositionStep_mm;            // mm per position count
  double position_offset_mm = 0.0;                       // mm at 0 counts (a joint's angle as a muscle's contraction)
  double command_full_counts = kAnalogFullScaleCounts;   // valve counts at full scale (10 V) above the zero
  double command_zero_counts = 0.0;                      // counts for 0 V
  double pressure_full_counts = kAnalogFullScaleCounts;  // pressure feedback counts at full scale (10 bar)

  double mm(double counts) const noexcept { return position_offset_mm + counts * position_step_mm; }
  // Command u [V relative to mid-range] -> the valve's counts (clamped to 0..10 V and to 16 bits).
  std::int16_t commandCounts(double u) const noexcept {
    const double v = std::clamp(valveVolts(u), 0.0, kValveFullScale_V);
    const long c = std::lround(command_zero_counts + v * command_full_counts / kValveFullScale_V);
    return static_cast<std::int16_t>(std::clamp(c, -32768L, 32767L));
  }
  // The inverse: the valve's counts -> command u (what a valve that counts so outputs).
  double commandFromCounts(double counts) const noexcept {
    return commandFromVolts((counts - command_zero_counts) * kValveFullScale_V / command_full_counts);
  }
  // The sensor's counts for a position, the valve's feedback counts for a pressure (clamped as above).
  std::int32_t positionCounts(double y_mm) const noexcept {
    return static_cast<std::int32_t>(
        std::lround(std::clamp((y_mm - position_offset_mm) / position_step_mm, -2.0e9, 2.0e9)));
  }
  std::int16_t pressureCounts(double bar) const noexcept {
    return static_cast<std::int16_t>(
        std::lround(std::clamp(bar, 0.0, kPressureFullScale_bar) * pressure_full_counts / kPressureFullScale_bar));
  }
  double bar(double counts) const noexcept { return counts * kPressureFullScale_bar / pressure_full_counts; }
  bool isDefault() const noexcept {
    return position_step_mm == kPositionStep_mm && position_offset_mm == 0.0 &&
           command_full_counts == kAnalogFullScaleCounts && command_zero_counts == 0.0;
  }
};

}  // namespace pamc::nodes::pd
