// The object dictionary an EDS or DCF describes: the parsed file (eds.hpp) made into storage
// (od.hpp), with $NODEID resolved. Kept apart so that the dictionary knows nothing of files.
#pragma once

#include <cstdint>
#include <string>

#include "canopen/concise_dcf.hpp"
#include "canopen/eds.hpp"
#include "canopen/od.hpp"

namespace pamc::canopen {

// Builds the dictionary of an EDS file; $NODEID in values becomes node_id. Throws EdsError.
// values (a DCF's, a rig file compiled into a master's objects) replace the EDS defaults of their
// entries: they are the defaults a reset restores. Throws OdError for an entry the EDS does not have
// or a value of the wrong size.
ObjectDictionary dictionaryFromEds(const EdsFile& eds, std::uint8_t node_id, const ConciseDcf& values = {});
// Loads and parses an EDS file; node_id 0 takes [DeviceComissioning] NodeID from the file. Throws EdsError.
ObjectDictionary loadDictionary(const std::string& eds_path, std::uint8_t node_id = 0);
// The node-ID to use: the given one, else the EDS's [DeviceComissioning] NodeID; 1..127 or EdsError.
std::uint8_t resolveNodeId(const EdsFile& eds, const std::string& eds_path, std::uint8_t node_id);

}  // namespace pamc::canopen
