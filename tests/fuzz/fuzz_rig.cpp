// fuzz_rig: rig file text through parseRigFile (what `--rig FILE` runs on a file), with the EDS paths
// relative to od/rigs/ so that the project's EDS files can be named. Documented errors: RigError, one
// line starting with the rig's name; EdsError for a slave EDS, one line starting with that file. An
// accepted rig must be usable: distinct node-IDs, COB-IDs within 11 bits, a boot plan for each slave.
#include <cstdint>
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
  if (rig.sensor_id == rig.valve_id || rig.sensor_id == rig.controller_id || rig.valve_id == rig.controller_id)
    finding("accepted two nodes on one node-ID");
  for (std::uint32_t cob : {rig.layout.sensor_cob, rig.layout.valve_cob, rig.layout.feedback_cob})
    if (cob > 0x7FF) finding("accepted a COB-ID beyond 11 bits");
  if ((rig.sensor_boot.assignment & pamc::canopen::kAssignSlave) == 0 || (rig.valve_boot.assignment & pamc::canopen::kAssignSlave) == 0)
    finding("accepted a rig without a boot plan");
  (void)pamc::nodes::masterValues(rig);
  return 0;
}
