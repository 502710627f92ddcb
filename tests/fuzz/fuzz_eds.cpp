// fuzz_eds: EDS text through everything that reads an EDS file -
//   EdsFile::parse -> ObjectDictionary::fromEds -> a Node configured from that dictionary, booted, made
//   Operational, reset once and run for 5 ms of virtual time -> loadBusDictionary (the decoder's view).
// Documented errors: EdsError (parser, dictionary values), OdError (a dictionary a node cannot run),
// std::runtime_error from loadBusDictionary. Each must be one line; the file readers' errors start with
// the file name. Anything else (another exception, a crash, a sanitizer report) is a finding.
#include <cstdint>
#include <string>

#include "canopen/eds_dictionary.hpp"
#include "canopen/node.hpp"
#include "fuzz_util.hpp"
#include "nodes/decoder.hpp"

using namespace pamc::canopen;

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static pamc::fuzz::InputFile file;
  const std::string text(reinterpret_cast<const char*>(data), size);
  EdsFile eds;
  try {
    eds = EdsFile::parse(text, "fuzz.eds");
  } catch (const EdsError& e) {
    pamc::fuzz::checkMessage(e.what(), "fuzz.eds");
    return 0;
  }

  const std::uint8_t id = eds.node_id != 0 ? eds.node_id : 1;
  try {
    ObjectDictionary od = dictionaryFromEds(eds, id);
    VirtualBus bus(0, 256);
    VirtualBus::Port& tool = bus.addPort();
    VirtualBus::Port& port = bus.addPort();
    try {
      Node node(std::move(od), id, port);
      port.setClient(&node);
      node.start(bus.now());
      bus.flush();
      const std::uint8_t start[2] = {0x01, 0x00};
      tool.send(makeFrame(0x000, 2, start));
      bus.advanceTo(2000);
      const std::uint8_t reset[2] = {0x82, 0x00};  // reset communication: defaults back, reconfigure
      tool.send(makeFrame(0x000, 2, reset));
      tool.send(makeFrame(0x000, 2, start));
      bus.advanceTo(5000);
    } catch (const OdError& e) {
      pamc::fuzz::checkMessage(e.what(), "");
    }
  } catch (const EdsError& e) {
    pamc::fuzz::checkMessage(e.what(), "fuzz.eds");
  } catch (const OdError& e) {
    pamc::fuzz::checkMessage(e.what(), "");
  }

  // The decoder reads the same file by path.
  const std::string& path = file.write(data, size);
  try {
    const pamc::nodes::BusDictionary dict = pamc::nodes::loadBusDictionary({path});
    for (const auto& [cob, layout] : dict.pdos) {
      if (cob > kStandardIdMask) pamc::fuzz::finding("decoder PDO with a COB-ID above 0x7FF");
      if (layout.length > 8) pamc::fuzz::finding("decoder PDO layout longer than 8 bytes");
    }
  } catch (const std::runtime_error& e) {
    pamc::fuzz::checkMessage(e.what(), path);
  }
  return 0;
}
