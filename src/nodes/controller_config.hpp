// The controller node's configuration: what the command line and a rig file choose (the dictionary's
// defaults otherwise), and the slaves as a rig file describes them.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "canopen/nmt_master.hpp"
#include "control/controller.hpp"
#include "control/trajectory.hpp"
#include "nodes/process_data.hpp"

namespace pamc::nodes {

// The slaves as a rig file describes them (nodes/rig_file.hpp): where their process data are and how to
// scale them; the defaults are pamc's own devices with the layout of od/*.eds. What the controller
// writes into them at their boot is in its dictionary (ControllerNodeConfig::dictionary).
struct SlaveLayout {
  pd::Scaling scaling;
  std::uint32_t sensor_cob = 0;    // COB-ID of the sensor's position PDO (0: the controller EDS's 0x1400:01)
  std::uint32_t valve_cob = 0;     // COB-ID of the valve's command PDO (0: 0x1800:01)
  std::uint32_t feedback_cob = 0;  // COB-ID of the valve's feedback PDO (0: 0x1401:01)
  bool feedback = true;            // the valve sends its pressure; its absence is a fault
  // The valve's error value (CiA 401 0x6444:n for the output 0x6411:n); index 0: none to write.
  std::uint16_t error_value_index = 0x6444;
  std::uint8_t error_value_sub = 1;
  bool position_step_from_device = false;  // the step is read from the sensor at its boot (0x6005:01, nm)
};

// A node runs at most this many channels (the controller's dictionary has the objects of eight).
inline constexpr std::size_t kMaxChannels = 8;

// The controller's own objects of channel c (0-based), 0x10 apart as CiA 301 lays out the virtual
// devices of a module: the position it receives, the pressure it receives, the command it sends.
constexpr std::uint16_t positionObject(std::size_t c) { return static_cast<std::uint16_t>(0x3000 + 0x10 * c); }
constexpr std::uint16_t pressureObject(std::size_t c) { return static_cast<std::uint16_t>(0x3001 + 0x10 * c); }
constexpr std::uint16_t commandObject(std::size_t c) { return static_cast<std::uint16_t>(0x3002 + 0x10 * c); }

// One channel: one muscle's position input, valve output and control loop. Where its numbers are on
// the bus (its sensor and valve slaves - one slave may serve several channels - their COB-IDs and
// scaling) and which of the controller's PDOs carry them; and what it runs where a rig file gives it
// its own (unset: the node's, i.e. the dictionary's and the command line's).
struct ChannelConfig {
  std::uint8_t sensor_id = 2, valve_id = 3;
  SlaveLayout layout;
  // The controller's RPDO bringing the position, its RPDO bringing the pressure (with layout.feedback)
  // and its TPDO taking the command.
  unsigned position_rpdo = 1, feedback_rpdo = 2, command_tpdo = 1;
  int kind = -1;  // control::Kind; -1: 0x2010
  std::optional<model::Model> model;
  std::optional<control::Trajectory> trajectory;
  // Its joint partner (0-based; -1: none): a fault of either puts both at their safe values.
  int partner = -1;
  // A muscle of an antagonistic joint: its position is the joint's angle seen through the lever (the
  // scaling's step and offset), received into this object of the controller (0: its own,
  // positionObject(c); the joint's second muscle reads the first's); and its command gets the joint's
  // co-contraction on top of its loop's [V].
  std::uint16_t position_object = 0;
  double command_offset_v = 0.0;
  // Its setpoint: its trajectory (its own or the node's) seen through setpoint = offset + scale x value -
  // a joint's angle in degrees as this muscle's contraction in mm.
  double setpoint_scale = 1.0, setpoint_offset = 0.0;
};

struct ControllerNodeConfig {
  std::string eds_path = "od/controller.eds";
  std::uint8_t node_id = 0;  // 0: the EDS's
  // Overrides of the object dictionary's defaults (unset: the EDS value).
  int kind = -1;                   // control::Kind
  control::ControllerConfig ctrl;  // the model (and, with gains_from_config, the gains)
  bool gains_from_config = false;  // write ctrl's gains and UKF settings into the OD instead of reading them
  // Cycles from a command to the position that shows it, beyond one sample: 2 with this node's
  // timing (a synchronous valve RPDO, a sensor sending right after the SYNC); other slaves may differ.
  int delay_cycles = control::kBusDelayCycles;
  bool has_trajectory = false;
  control::Trajectory trajectory;
  double preroll_s = 5.0;  // hold the first setpoint this long before the trajectory starts
  bool produce_sync = true;
  unsigned period_us = 0;  // SYNC period override (0: 0x1006 of the EDS)
  // A fault's causes must be gone this long before control resumes: 500 cycles at the design's 1 kHz,
  // 50 at 100 Hz (whole cycles of 0x1006, at least one).
  double recover_s = 0.5;
  double ramp_mm_per_s =
      10.0;                   // after recovery or a commit the setpoint returns at most this fast (V/s for Kind::Input)
  double ramp_slew_v = 0.02;  // ... and the command changes at most this much per cycle [V]
  double no_position_s =
      1.0;  // no position this long after entering Operational (or after the sensor's boot): Fault::NoPosition
  // The channels, in order (channel 1 first); one by default: pamc's own sensor and valve.
  std::vector<ChannelConfig> channels{ChannelConfig{}};
  // A fault of one channel puts every channel at its safe value (a rig file's `faults = all`);
  // otherwise only the channel and its joint partner.
  bool fault_all = false;
  // Values of the controller's own dictionary in place of the EDS defaults (a reset restores them):
  // a rig file compiled (masterValues), a DCF (--dcf). The boot of the slaves follows them: 0x1F22,
  // 0x1F80, 0x1F81, 0x1F84-0x1F89, 0x1016 (canopen/nmt_master.hpp).
  canopen::ConciseDcf dictionary;
  // The controller of an SDO commit built on a worker thread instead of in the SDO server (on a rig; in
  // virtual time the inline build keeps runs deterministic). docs/PERFORMANCE.md has what it saves.
  bool build_off_cycle = false;
  // Boot reports of the slaves (configured, or why not); called on the node's thread, outside the cycle.
  std::function<void(const std::string&)> log;
};

}  // namespace pamc::nodes
