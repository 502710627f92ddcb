// A rig file: one INI file with everything the controller must know about the rig it runs on - the
// bus, its own node, and per slave (the position sensor, the valve) its node-ID and EDS, the identity
// it must report, which object carries the position or takes the command and how to scale it, and
// what to write into it at its boot. docs/RIG.md has every key; od/rigs/default.ini is pamc's own rig.
//
// The slaves' EDS files are read here (to find the objects, their types and PDOs), so that the
// configuration the controller writes at boot is complete and checked before anything goes on the bus.
// masterValues() compiles the file into the controller's own dictionary (CiA 302: 0x1F22, 0x1F80,
// 0x1F81, 0x1F84-0x1F89, 0x1016, and its PDOs), as Lely's dcfgen compiles its YAML into a master DCF;
// the controller's boot then follows its dictionary.
//
// Two forms: one muscle ([sensor] and [valve] with the objects in them, od/rigs/default.ini), or
// several ([slave.NAME] per slave, [channel.N] per muscle naming its sensor and valve slaves and
// their objects, od/rigs/four_muscles.ini). A slave serving several channels carries them in one PDO
// (a four-output module's setpoints in one RPDO), in channel order.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "nodes/controller_node.hpp"

namespace pamc::nodes {

// The CAN interface of a rig file without `interface`, and of the commands' --iface without a rig file.
inline constexpr const char* kDefaultInterface = "can0";

// "file:line: problem" (line 0: the file as a whole).
class RigError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// An object of a slave the cycle carries: where it is and its type (from the slave's EDS).
struct RigObject {
  std::uint16_t index = 0;  // 0: none
  std::uint8_t sub = 0;
  canopen::DataType type = canopen::DataType::Integer32;
};

// A slave as the rig file describes it: its name ("sensor" and "valve" in the one-muscle form, NAME
// of [slave.NAME] otherwise), node-ID, EDS, what to check and write at its boot, its heartbeat.
struct RigSlave {
  std::string name;
  std::uint8_t id = 0;
  std::string eds;            // resolved path
  canopen::SlaveBoot boot;    // 0x1F81, identity, configuration
  unsigned heartbeat_ms = 0;  // its heartbeat period once booted: heartbeat_ms, or else its EDS's 0x1017 (0: none)
};

// A channel as the rig file describes it: its configuration for the controller node (which slaves,
// their COB-IDs and scaling, the controller's PDOs), and its objects in the slaves' PDOs with their
// byte offsets there (several channels may share one PDO).
struct RigChannel {
  ChannelConfig cfg;
  RigObject position, command, feedback;                                  // feedback.index 0: none
  unsigned position_offset = 0, command_offset = 0, feedback_offset = 0;  // bytes into the PDO
};

// An antagonistic joint: two channels' muscles on one joint, its angle measured by one encoder. The
// flexor contracts as the angle grows: contraction = rest + lever x angle, the extensor's rest - lever x angle.
struct RigJoint {
  std::size_t flexor = 0, extensor = 1;  // channels (0-based)
  std::uint8_t sensor_id = 0;            // the angle encoder
  double angle_step_deg = 0.001;         // degrees per count
  double angle_zero_counts = 0.0;        // counts at angle 0
  double lever_mm = 25.0;                // pulley radius: mm of contraction per radian
  double rest_mm = 15.0;                 // each muscle's contraction at angle 0
  double stiffness_v = 0.0;              // co-contraction: on both muscles' commands [V]
};

struct RigFile {
  std::string path;
  std::string interface = kDefaultInterface;
  unsigned bitrate = 1000000;
  unsigned period_us = 1000;
  std::uint8_t controller_id = 1;
  std::string controller_eds;  // resolved path
  std::uint32_t startup = canopen::kStartupMaster;
  unsigned boot_time_ms = 0;  // 0x1F89 (0: no limit)
  bool fault_all = false;     // [controller] faults = all: one channel's fault stops every channel
  // Written in the one-muscle form ([sensor], [valve]) rather than with [slave.NAME] and [channel.N]
  // sections (still read: one channel).
  bool one_muscle_form = false;
  std::vector<RigSlave> slaves;      // in the file's order
  std::vector<RigChannel> channels;  // channel 1 first
  std::vector<RigJoint> joints;
  unsigned controller_rpdos = 0, controller_tpdos = 0;  // the PDOs of the controller's EDS

  const RigSlave& slave(std::uint8_t id) const;  // throws std::out_of_range for a node-ID not in the file
};

// What the controller consumes of a slave's heartbeat (0x1016): twice its period plus 50 ms - one
// heartbeat may be late by a whole period and the scheduling of both nodes before the slave counts as
// lost (100 ms: 250 ms). 0: not supervised.
constexpr unsigned consumerHeartbeatMs(unsigned producer_ms) {
  const unsigned ms = producer_ms == 0 ? 0 : 2 * producer_ms + 50;
  return ms > 0xFFFF ? 0xFFFF : ms;
}

// Reads and checks a rig file; throws RigError (or EdsError for a bad slave EDS) naming file and line.
RigFile readRigFile(const std::string& path);
// The same for text already in memory; path names it in errors and EDS paths are relative to its folder.
RigFile parseRigFile(const std::string& text, const std::string& path);

// The rig file compiled into values of the controller's dictionary: 0x1F80 start-up; per slave 0x1F81
// assignment, 0x1F84-0x1F88 identity (0: not checked), 0x1F22 concise DCF; 0x1F89 boot time; 0x1016
// consumer heartbeat times (consumerHeartbeatMs); the controller's RPDOs and TPDOs on the slaves'
// COB-IDs, mapped to its channels' objects (0x3000 + 0x10 c), the others off.
canopen::ConciseDcf masterValues(const RigFile& rig);

// The node settings the rig file makes: node-IDs, EDS, period, the channels, and masterValues() as the
// dictionary's values. The rest of cfg is kept.
void applyRig(const RigFile& rig, ControllerNodeConfig& cfg);

}  // namespace pamc::nodes
