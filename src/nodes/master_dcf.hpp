// `pamc controller --dcf FILE`: a master DCF (CiA 306), written by hand or by another tool, for the
// controller node. Every value it gives replaces the controller EDS's default in the node's dictionary,
// on top of the rig file's (ControllerNodeConfig::dictionary), so the slaves' boot follows it: 0x1F22
// concise DCFs (hex in ParameterValue, or a binary file named by UploadFile / DownloadFile), 0x1F80,
// 0x1F81, 0x1F84-0x1F89, 0x1016, the PDOs. Its [DeviceComissioning] NodeID is the controller's.
#pragma once

#include <string>

#include "nodes/controller_config.hpp"

namespace pamc::nodes {

// Throws canopen::EdsError "file:line: [section] problem": a malformed file, an entry the controller
// does not have or of another type, a value beyond its limits, a 0x1F22 that is not a concise DCF.
void applyMasterDcf(const std::string& path, ControllerNodeConfig& cfg);

}  // namespace pamc::nodes
