// Shared helpers of the CANopen tests: EDS text builder, frame recorder, a small network on the virtual bus.
#pragma once

#include <gtest/gtest.h>

#include <cstdio>
#include <memory>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "canopen/candump_log.hpp"
#include "canopen/eds_dictionary.hpp"
#include "canopen/node.hpp"

namespace pamc::canopen::test {

inline std::string odPath(const char* file) { return std::string(PAMC_OD_DIR) + "/" + file; }

// Minimal valid EDS around the given object sections; the object lists are derived from the sections.
inline std::string makeEds(const std::string& objects, int node_id = 5) {
  std::set<unsigned> indices = {0x1000, 0x1001, 0x1018};
  std::regex header(R"(^\[([0-9A-Fa-f]{4})\]\s*$)");
  std::istringstream in(objects);
  for (std::string line; std::getline(in, line);) {
    std::smatch m;
    if (std::regex_match(line, m, header)) indices.insert(static_cast<unsigned>(std::stoul(m[1], nullptr, 16)));
  }
  std::vector<unsigned> optional, manufacturer;
  for (unsigned i : indices) {
    if (i == 0x1000 || i == 0x1001 || i == 0x1018) continue;
    (i >= 0x2000 && i <= 0x5FFF ? manufacturer : optional).push_back(i);
  }
  auto list = [](const char* name, const std::vector<unsigned>& v) {
    std::string s = std::string("[") + name + "]\nSupportedObjects=" + std::to_string(v.size()) + "\n";
    for (std::size_t i = 0; i < v.size(); ++i) {
      char buf[32];
      std::snprintf(buf, sizeof buf, "%zu=0x%04X\n", i + 1, v[i]);
      s += buf;
    }
    return s + "\n";
  };
  std::string s =
      "[FileInfo]\nFileName=test.eds\nEDSVersion=4.0\n\n"
      "[DeviceInfo]\nVendorName=test\nProductName=test\n\n"
      "[DeviceComissioning]\nNodeID=" +
      std::to_string(node_id) + "\n\n" + list("MandatoryObjects", {0x1000, 0x1001, 0x1018}) +
      list("OptionalObjects", optional) + list("ManufacturerObjects", manufacturer) +
      "[1000]\nParameterName=Device type\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\n\n"
      "[1001]\nParameterName=Error register\nDataType=0x0005\nAccessType=ro\nDefaultValue=0\n\n"
      "[1018]\nParameterName=Identity\nObjectType=0x9\nSubNumber=2\n\n"
      "[1018sub0]\nParameterName=Highest sub-index\nDataType=0x0005\nAccessType=ro\nDefaultValue=1\n\n"
      "[1018sub1]\nParameterName=Vendor-ID\nDataType=0x0007\nAccessType=ro\nDefaultValue=0\n\n";
  return s + objects;
}

// One VAR section.
inline std::string var(unsigned index, const std::string& name, const char* type, const char* access,
                       const std::string& def, int pdo = 0, const std::string& extra = "") {
  char buf[16];
  std::snprintf(buf, sizeof buf, "[%04X]\n", index);
  return std::string(buf) + "ParameterName=" + name + "\nObjectType=0x7\nDataType=" + type + "\nAccessType=" + access +
         "\nDefaultValue=" + def + "\nPDOMapping=" + std::to_string(pdo) + "\n" + extra + "\n";
}

inline ObjectDictionary odFromText(const std::string& text, std::uint8_t node_id) {
  return dictionaryFromEds(EdsFile::parse(text, "test.eds"), node_id);
}

inline Frame frame(const std::string& token) {
  Frame f;
  std::string err;
  if (!parseFrame(token, f, &err)) ADD_FAILURE() << "bad frame literal " << token << ": " << err;
  return f;
}

struct Logged {
  TimeUs t;
  std::string frame;
};

// Records every frame on the bus as "ID#DATA" with its virtual time.
class Recorder {
 public:
  explicit Recorder(VirtualBus& bus) {
    bus.addTap([this](const Frame& f, TimeUs now) { log.push_back({now, formatFrame(f)}); });
  }
  std::vector<std::string> frames() const {
    std::vector<std::string> v;
    for (const auto& l : log) v.push_back(l.frame);
    return v;
  }
  // Frames whose text starts with prefix (e.g. "581#").
  std::vector<Logged> matching(const std::string& prefix) const {
    std::vector<Logged> v;
    for (const auto& l : log) {
      if (l.frame.compare(0, prefix.size(), prefix) == 0) v.push_back(l);
    }
    return v;
  }
  std::vector<std::string> take() {
    auto v = frames();
    log.clear();
    return v;
  }
  std::vector<Logged> log;
};

// A virtual bus with a tool port (a test's "cansend") and nodes attached as clients.
class Network {
 public:
  Network() : recorder(bus), tool(bus.addPort()) {}

  Node& addEds(const std::string& path, std::uint8_t node_id = 0, NodeOptions options = {}) {
    VirtualBus::Port& port = bus.addPort();
    nodes.push_back(Node::fromEds(path, port, node_id, options));
    port.setClient(nodes.back().get());
    return *nodes.back();
  }
  Node& addText(const std::string& eds_text, std::uint8_t node_id, NodeOptions options = {}) {
    VirtualBus::Port& port = bus.addPort();
    nodes.push_back(std::make_unique<Node>(odFromText(eds_text, node_id), node_id, port, options));
    port.setClient(nodes.back().get());
    return *nodes.back();
  }
  void startAll() {
    for (auto& n : nodes) n->start(bus.now());
    bus.flush();
  }
  // Sends a frame from the tool port and delivers everything it triggers.
  void send(const std::string& token) {
    tool.send(frame(token));
    bus.flush();
  }
  // Sends a request and returns the frames that followed it (excluding the request).
  std::vector<std::string> exchange(const std::string& token) {
    recorder.log.clear();
    send(token);
    auto v = recorder.frames();
    if (!v.empty()) v.erase(v.begin());
    return v;
  }

  VirtualBus bus;
  Recorder recorder;
  VirtualBus::Port& tool;
  std::vector<std::unique_ptr<Node>> nodes;
};

}  // namespace pamc::canopen::test
