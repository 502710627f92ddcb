#include "canopen/eds_dictionary.hpp"

#include <algorithm>
#include <utility>

namespace pamc::canopen {

ObjectDictionary dictionaryFromEds(const EdsFile& eds, std::uint8_t node_id, const ConciseDcf& values) {
  std::vector<ObjectInfo> objects;
  std::vector<EntrySpec> specs;
  for (const EdsObject& obj : eds.objects) {
    ObjectInfo info;
    info.index = obj.index;
    info.type = obj.object_type;
    info.name = obj.name;
    objects.push_back(info);
    for (const EdsSubObject& sub : obj.subs) {
      EntrySpec s;
      s.index = obj.index;
      s.sub = sub.sub_index;
      s.name = sub.name;
      s.type = sub.data_type;
      s.access = sub.access;
      s.pdo_mappable = sub.pdo_mapping;
      auto encode = [&](const std::string& text, int line, const char* key, std::vector<std::uint8_t>& out) {
        std::string err = encodeEdsValue(text, sub.data_type, node_id, out);
        if (!err.empty()) throw EdsError(eds.file, line, sub.section, std::string(key) + ": " + err);
      };
      encode(sub.default_value, sub.default_line, "DefaultValue", s.default_value);
      if (!sub.low_limit.empty()) encode(sub.low_limit, sub.low_line, "LowLimit", s.low_limit);
      if (!sub.high_limit.empty()) encode(sub.high_limit, sub.high_line, "HighLimit", s.high_limit);
      specs.push_back(std::move(s));
    }
  }
  for (const DcfEntry& v : values) {
    auto it = std::find_if(specs.begin(), specs.end(),
                           [&](const EntrySpec& s) { return s.index == v.index && s.sub == v.sub; });
    if (it == specs.end())
      throw OdError(eds.file + " has no entry " + entryName(v.index, v.sub) + " for the value given");
    const std::size_t fixed = dataTypeSize(it->type);
    if (fixed != 0 && v.data.size() != fixed)
      throw OdError(entryName(v.index, v.sub) + ": a value of " + std::to_string(v.data.size()) + " bytes for " +
                    dataTypeName(it->type));
    it->default_value = v.data;
  }
  return ObjectDictionary(std::move(objects), std::move(specs));
}

std::uint8_t resolveNodeId(const EdsFile& eds, const std::string& eds_path, std::uint8_t node_id) {
  if (node_id == 0) node_id = eds.node_id;
  if (node_id == 0 || node_id > 127) {
    throw EdsError(eds_path, 0, "DeviceComissioning",
                   "no valid node-ID given and none in [DeviceComissioning] NodeID (1..127)");
  }
  return node_id;
}

ObjectDictionary loadDictionary(const std::string& eds_path, std::uint8_t node_id) {
  EdsFile eds = EdsFile::load(eds_path);
  return dictionaryFromEds(eds, resolveNodeId(eds, eds_path, node_id));
}

}  // namespace pamc::canopen
