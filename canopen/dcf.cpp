#include "canopen/dcf.hpp"

#include <fstream>
#include <sstream>

namespace pamc::canopen {

namespace {

const EdsSubObject* findSub(const EdsFile& eds, std::uint16_t index, std::uint8_t sub) {
  const EdsObject* o = eds.find(index);
  if (o == nullptr) return nullptr;
  for (const auto& s : o->subs)
    if (s.sub_index == sub) return &s;
  return nullptr;
}

// One value of the DCF against the device's entry: present, same type, within the device's limits.
DcfValue checked(const EdsFile& dcf, const EdsFile& device, std::uint8_t node_id, const EdsObject& o,
                 const EdsSubObject& s) {
  auto fail = [&](const std::string& problem) { throw EdsError(dcf.file, s.default_line, s.section, problem); };
  const std::string at = entryName(o.index, s.sub_index);
  const EdsSubObject* d = findSub(device, o.index, s.sub_index);
  if (d == nullptr) fail("the device (" + device.file + ") has no entry " + at);
  if (d->data_type != s.data_type)
    fail(at + " is " + dataTypeName(s.data_type) + " here but " + dataTypeName(d->data_type) + " in " + device.file);
  DcfValue v{DcfEntry{o.index, s.sub_index, {}}, s.default_line, s.section};
  const std::string problem = encodeEdsValue(s.default_value, s.data_type, node_id, v.entry.data);
  if (!problem.empty()) fail(problem);
  if (!isNumeric(d->data_type)) return v;
  bool unordered = false;
  for (const auto& [text, below] :
       {std::pair<const std::string*, bool>{&d->low_limit, true}, {&d->high_limit, false}}) {
    std::vector<std::uint8_t> limit;
    if (text->empty() || !encodeEdsValue(*text, d->data_type, node_id, limit).empty()) continue;
    const int c = compareValues(d->data_type, v.entry.data.data(), limit.data(), unordered);
    if (below ? c < 0 : c > 0)
      fail(at + " = " + s.default_value + " is " + (below ? "below" : "above") + " the device's " +
           (below ? "LowLimit " : "HighLimit ") + *text);
  }
  return v;
}

Dcf fromEds(const EdsFile& dcf, const EdsFile& device) {
  Dcf out;
  out.file = dcf.file;
  out.node_id = dcf.node_id;
  const std::uint8_t node_id = dcf.node_id != 0 ? dcf.node_id : (device.node_id != 0 ? device.node_id : 1);
  for (const EdsObject& o : dcf.objects)
    for (const EdsSubObject& s : o.subs)
      if (s.valued) out.values.push_back(checked(dcf, device, node_id, o, s));
  return out;
}

}  // namespace

ConciseDcf Dcf::entries() const {
  ConciseDcf c;
  for (const auto& v : values) c.push_back(v.entry);
  return c;
}

Dcf readDcf(const std::string& path, const EdsFile& device) { return fromEds(EdsFile::load(path), device); }

Dcf parseDcf(const std::string& text, const std::string& path, const EdsFile& device) {
  return fromEds(EdsFile::parse(text, path), device);
}

}  // namespace pamc::canopen
