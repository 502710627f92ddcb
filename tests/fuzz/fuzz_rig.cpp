// fuzz_rig: rig file text through parseRigFile (what `--rig FILE` runs on a file), with the EDS paths
// relative to od/rigs/ so that the project's EDS files can be named. Documented errors: RigError, one
// line starting with the rig's name; EdsError for a slave EDS, one line starting with that file. An
// accepted rig must be usable: distinct node-IDs, COB-IDs within 11 bits, a boot plan for each slave.
#include <cstdint>
#include <set>
#include <string>

#include "canopen/eds.hpp"
#include "fuzz_util.hpp"
#include "nodes/rig_file.hpp"

using pamc::fuzz::finding;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  const std::string path = std::string(PAMC_OD_DIR) + "/rigs/fuzz.ini";
  pamc::nodes::RigFile rig;
  try {
    rig = pamc::nodes::parseRigFile(text, path);
  } catch (const pamc::nodes::RigError& e) {
    pamc::fuzz::checkMessage(e.what(), path);
    return 0;
  } catch (const pamc::canopen::EdsError& e) {
    pamc::fuzz::checkMessage(e.what(), e.file());
    return 0;
  }
  std::set<unsigned> ids = {rig.controller_id};
  for (const auto& s : rig.slaves) {
    if (!ids.insert(s.id).second) finding("accepted two nodes on one node-ID");
    if ((s.boot.assignment & pamc::canopen::kAssignSlave) == 0) finding("accepted a rig without a boot plan");
  }
  for (const auto& c : rig.channels)
    for (std::uint32_t cob : {c.cfg.layout.sensor_cob, c.cfg.layout.valve_cob, c.cfg.layout.feedback_cob})
      if (cob > 0x7FF) finding("accepted a COB-ID beyond 11 bits");
  if (rig.channels.empty()) finding("accepted a rig without a channel");
  (void)pamc::nodes::masterValues(rig);
  return 0;
}
