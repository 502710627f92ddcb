// Reading a bus through the EDS files: which COB-ID carries which object, in engineering units.
// Used by `pamc decode` (candump log -> measurement CSV) and `pamc monitor` (live view).
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "canopen/candump_log.hpp"
#include "canopen/frame.hpp"
#include "canopen/od.hpp"

namespace pamc::nodes {

struct PdoField {
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  canopen::DataType type = canopen::DataType::Unsigned8;
  std::uint8_t bytes = 0;
  std::string column;                // "sensor.position_value"
  std::string role;                  // "y", "u", "p" or ""
  double scale = 1.0, offset = 0.0;  // engineering value = raw * scale + offset
  std::string unit;
};

struct PdoLayout {
  std::uint32_t cob_id = 0;
  std::string device;  // EDS file stem
  std::uint8_t node_id = 0;
  std::vector<PdoField> fields;
  std::uint8_t length = 0;
};

struct BusDictionary {
  std::map<std::uint32_t, PdoLayout> pdos;    // by COB-ID
  std::map<std::uint8_t, std::string> nodes;  // node-ID -> device name
  std::uint32_t sync_cob = 0x80;
  double sync_period_s = 1e-3;  // 0x1006 of the SYNC producer, if any
};

// EDS files, or directories holding them. Throws canopen::EdsError / std::runtime_error.
BusDictionary loadBusDictionary(const std::vector<std::string>& paths);

struct RigFile;
// The rig's devices as the controller configures them (nodes/rig_file.hpp): the sensor's position,
// the valve's command and feedback on the rig's COB-IDs, in the rig's scaling; the SYNC period of the
// rig. A position step read from the device at boot is taken as its EDS's default.
// With several channels the roles of channel c (0-based) are channelRole("y", c) ("y2" for the second).
BusDictionary busDictionaryFromRig(const RigFile& rig);
std::string channelRole(const char* role, std::size_t c);

// Decodes one PDO's fields into engineering values (false on a length mismatch).
bool decodePdo(const PdoLayout& l, const canopen::Frame& f, std::vector<double>& out);

struct DecodedRun {
  std::vector<std::string>
      columns;  // t, u, y, p, t_log, u2, y2, p2, ... (channels 2..), then every other mapped object
  std::vector<std::vector<double>> rows;
  std::uint64_t frames = 0, syncs = 0, unknown = 0, bad_length = 0;
  std::uint64_t held = 0;  // cycles without a position PDO (last value held)
};

// One row per SYNC cycle k: the values the nodes sent after SYNC k, and as u the valve command in
// effect during the cycle that ended with SYNC k (latched by the valve at SYNC k-1) - the timing of
// a measurement file, where u is the command in effect when y was taken. t = SYNC index x period; a
// value lost in a cycle holds its last one (counted in `held`), so the time base stays even.
DecodedRun decodeCandump(const std::vector<canopen::CandumpRecord>& log, const BusDictionary& dict);

}  // namespace pamc::nodes
