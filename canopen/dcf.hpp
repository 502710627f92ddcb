// A device configuration file (CiA 306 DCF) read against the EDS of the device it configures: the
// values it gives (ParameterValue, else DefaultValue; a DOMAIN's also as UploadFile / DownloadFile; a
// CompactSubObj object's in its [xxxxValue] section), each checked - the device has the entry, with the
// same data type, and the value is within the device's limits. Entries the DCF only describes (no
// value) are left alone.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "canopen/concise_dcf.hpp"
#include "canopen/eds.hpp"

namespace pamc::canopen {

struct DcfValue {
  DcfEntry entry;  // encoded as the device stores it ($NODEID resolved)
  int line = 0;    // where the value is given
  std::string section;
};

struct Dcf {
  std::string file;
  std::uint8_t node_id = 0;  // [DeviceComissioning] NodeID (0: not given)
  std::vector<DcfValue> values;
  ConciseDcf entries() const;
};

// Throws EdsError ("file:line: [section] problem"): a malformed file, or a value the device cannot take.
// $NODEID is the DCF's NodeID, else the device EDS's.
Dcf readDcf(const std::string& path, const EdsFile& device);
Dcf parseDcf(const std::string& text, const std::string& path, const EdsFile& device);

}  // namespace pamc::canopen
