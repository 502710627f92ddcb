// fuzz_dcf: master DCF text through what `pamc controller --dcf FILE` runs on it - applyMasterDcf against
// od/controller.eds on top of the default rig's values - then the controller's dictionary built from it
// and each slave's boot read back from that dictionary (bootFromDictionary). Documented errors:
// EdsError, one line starting with the DCF's path. An accepted DCF must give a dictionary whose 0x1F22
// entries decode.
#include <cstdint>
#include <string>

#include "canopen/eds_dictionary.hpp"
#include "canopen/nmt_master.hpp"
#include "fuzz_util.hpp"
#include "nodes/master_dcf.hpp"
#include "nodes/rig_file.hpp"

using pamc::fuzz::finding;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static pamc::fuzz::InputFile file;
  static const pamc::nodes::RigFile rig = pamc::nodes::readRigFile(std::string(PAMC_OD_DIR) + "/rigs/default.ini");
  pamc::nodes::ControllerNodeConfig cfg;
  pamc::nodes::applyRig(rig, cfg);
  const std::string& path = file.write(data, size);
  try {
    pamc::nodes::applyMasterDcf(path, cfg);
  } catch (const pamc::canopen::EdsError& e) {
    pamc::fuzz::checkMessage(e.what(), path);
    return 0;
  }
  const auto eds = pamc::canopen::EdsFile::load(cfg.eds_path);
  const auto od = pamc::canopen::dictionaryFromEds(eds, cfg.node_id ? cfg.node_id : 1, cfg.dictionary);
  for (std::uint8_t id = 1; id <= 127; ++id) {
    pamc::canopen::SlaveBoot boot;
    if (!pamc::canopen::bootFromDictionary(od, id, boot, nullptr)) finding("accepted a 0x1F22 that does not decode");
  }
  return 0;
}
