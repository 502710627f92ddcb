// What the emulator plays (its devices, their plant, the faults it injects from the start) and the
// faults switched at run time.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "canopen/frame.hpp"
#include "nodes/process_data.hpp"
#include "plant/joint.hpp"
#include "plant/plant.hpp"

namespace pamc::nodes {

struct EmulatorConfig {
  std::string sensor_eds = "od/sensor.eds";
  std::string valve_eds = "od/valve.eds";
  // The devices: node-IDs (0: the EDS's), which objects carry the numbers and how they count. The
  // defaults are od/sensor.eds and od/valve.eds; profileDevices() the off-the-shelf kind.
  std::uint8_t sensor_id = 0, valve_id = 0;
  std::uint16_t position_index = 0x6004;
  std::uint8_t position_sub = 0;
  std::uint16_t command_index = 0x6411;
  std::uint8_t command_sub = 1;  // CiA 401: its error mode 0x6443 and error value 0x6444 have the same sub-index
  std::uint16_t pressure_index = 0x6401;
  std::uint8_t pressure_sub = 1;
  pd::Scaling scaling;
  // Several muscles (a rig with several channels), empty for one: the sensor at sensor_id, the valve at
  // valve_id.
  struct Muscles {
    // Channel c is measured by an encoder of its own (sensor_eds at node sensor_ids[c]) and driven by
    // output command_sub + c of the valve module, its pressure on input pressure_sub + c
    // (od/profile/analog401.eds has four); each muscle is a plant of its own - the same physics, its own
    // noise (seed + c).
    std::vector<std::uint8_t> sensor_ids;
    // The valve module of each channel (empty: all on valve_id): a rig of more muscles than one module
    // has outputs drives them from several modules (valve_eds each), a channel on the module's next
    // output after the channel before it on the same module.
    std::vector<std::uint8_t> valve_ids;
    // Antagonistic joints: two channels' muscles on one joint (plant/joint.hpp), its angle measured by
    // the sensor both channels name in sensor_ids, in counts of angle_step_deg from angle_zero_counts at 0.
    struct Joint {
      std::size_t flexor = 0, extensor = 1;
      plant::JointConfig mech;
      double angle_step_deg = 0.001, angle_zero_counts = 0.0;
    };
    std::vector<Joint> joints;
  } muscles;
  // The channel whose sensor the sensor faults act on (those above and Injection's).
  std::size_t fault_channel = 0;
  std::size_t channels() const { return muscles.sensor_ids.empty() ? 1 : muscles.sensor_ids.size(); }
  // A CiA 406 encoder (node 16, 5 um steps, asynchronous TPDO) and a CiA 401 analog I/O module (node 32,
  // valve on output 2, pressure on input 2, 0..20000 = full scale, no heartbeat) with their makers'
  // defaults (od/profile/): nothing fits pamc's controller until it configures them (od/rigs/profile.ini).
  static EmulatorConfig profileDevices(const std::string& od_dir);
  void useProfileDevices(const std::string& od_dir);  // the same on this configuration's devices
  plant::PlantConfig plant = plant::PlantConfig::defaults();
  double sensor_silent_at_s = -1;  // < 0: never
  double sensor_silent_for_s = 1e9;
  double drop_pdo_prob = 0.0;  // probability of dropping a position PDO
  int late_pdo_cycles = 0;     // position reported this many cycles late
  struct PayloadStep {
    double at_s = -1;  // < 0: no payload step
    double N = 40.0;
  } payload;
  std::uint64_t seed = 7;
};

// Faults switched at run time (by the fault rig or a test); they act from the next frame on.
struct Injection {
  bool sensor_silent = false;        // the sensor sends nothing and hears nothing
  bool valve_silent = false;         // the valve sends nothing (it still receives)
  canopen::TimeUs pdo_delay_us = 0;  // position PDOs leave this much later than sent
  bool pdo_duplicate = false;        // every position PDO goes out twice
  int pdo_len = -1;                  // position PDOs with this DLC (-1: as mapped)
  int heartbeat_len = -1;            // sensor heartbeats with this DLC (-1: 1)
  int drop_next = 0;                 // drop this many position PDOs in a row
  double drop_prob = 0.0;            // drop each position PDO with this probability (seeded)
};

}  // namespace pamc::nodes
