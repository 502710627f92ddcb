#include "nodes/master_dcf.hpp"

#include "canopen/dcf.hpp"

namespace pamc::nodes {

void applyMasterDcf(const std::string& path, ControllerNodeConfig& cfg) {
  const canopen::EdsFile device = canopen::EdsFile::load(cfg.eds_path);
  const canopen::Dcf dcf = canopen::readDcf(path, device);
  for (const auto& v : dcf.values) {
    const std::string problem = canopen::checkMasterEntry(v.entry);
    if (!problem.empty()) throw canopen::EdsError(dcf.file, v.line, v.section, problem);
    cfg.dictionary.push_back(v.entry);  // after the rig's: the DCF's value wins
  }
  if (dcf.node_id != 0) cfg.node_id = dcf.node_id;
}

}  // namespace pamc::nodes
