#include "canopen/eds.hpp"

#include "canopen/ini.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cfloat>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <set>
#include <sstream>

#include <sys/stat.h>

namespace pamc::canopen {

namespace {

std::string lower(std::string_view s) {
  std::string r(s);
  for (char& c : r) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return r;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

// A DOMAIN's file (UploadFile / DownloadFile) is read whole: a concise DCF, not a firmware image.
constexpr long kMaxDomainFile = 65536;

bool isHex(std::string_view s) {
  return !s.empty() &&
         std::all_of(s.begin(), s.end(), [](char c) { return std::isxdigit(static_cast<unsigned char>(c)) != 0; });
}

// Whole-string unsigned parse with C base prefixes (0x hex, leading 0 octal), as CiA 306 allows.
bool parseUnsigned(std::string_view text, std::uint64_t& out, int base = 0) {
  std::string s(trim(text));
  if (s.empty() || s[0] == '-' || s[0] == '+') return false;
  errno = 0;
  char* end = nullptr;
  unsigned long long v = std::strtoull(s.c_str(), &end, base);
  if (errno != 0 || end == s.c_str() || *end != '\0') return false;
  out = v;
  return true;
}

std::string quoted(std::string_view s) { return "'" + std::string(s) + "'"; }

class Checker {
 public:
  explicit Checker(std::string file) : file_(std::move(file)) {
    const auto slash = file_.find_last_of('/');
    dir_ = slash == std::string::npos ? std::string() : file_.substr(0, slash + 1);
  }

  [[noreturn]] void fail(int line, const std::string& section, const std::string& problem) const {
    throw EdsError(file_, line, section, problem);
  }
  [[noreturn]] void fail(const IniSection& s, const std::string& problem) const { fail(s.line, s.name, problem); }
  [[noreturn]] void fail(const IniSection& s, const IniKey& k, const std::string& problem) const {
    fail(k.line, s.name, k.name + ": " + problem);
  }

  const IniKey& require(const IniSection& s, const char* key, const char* written) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) fail(s, std::string("missing key ") + written);
    return *k;
  }

  std::uint64_t number(const IniSection& s, const IniKey& k, std::uint64_t max) const {
    std::uint64_t v = 0;
    if (!parseUnsigned(k.value, v)) fail(s, k, quoted(k.value) + " is not a number");
    if (v > max) fail(s, k, quoted(k.value) + " is out of range (max " + std::to_string(max) + ")");
    return v;
  }

  // Reads the entry keys shared by VAR sections, sub-object sections and CompactSubObj objects.
  void readEntry(const IniSection& s, EdsSubObject& e) const {
    e.section = s.name;
    e.line = s.line;
    e.name = require(s, "parametername", "ParameterName").value;
    const IniKey& dt = require(s, "datatype", "DataType");
    std::uint64_t code = number(s, dt, 0xFFFF);
    if (!isSupportedDataType(static_cast<std::uint16_t>(code))) {
      fail(s, dt, quoted(dt.value) + " is not a supported CiA 301 basic data type");
    }
    e.data_type = static_cast<DataType>(code);
    const IniKey& at = require(s, "accesstype", "AccessType");
    std::string a = lower(trim(at.value));
    if (a == "ro")
      e.access = Access::ReadOnly;
    else if (a == "wo")
      e.access = Access::WriteOnly;
    else if (a == "rw")
      e.access = Access::ReadWrite;
    else if (a == "rwr")
      e.access = Access::ReadWriteRead;
    else if (a == "rww")
      e.access = Access::ReadWriteWrite;
    else if (a == "const")
      e.access = Access::Const;
    else
      fail(s, at, quoted(at.value) + " is not one of ro, wo, rw, rwr, rww, const");
    if (const IniKey* k = s.find("pdomapping")) e.pdo_mapping = number(s, *k, 1) != 0;

    // DCF files carry the configured value in ParameterValue; it wins over DefaultValue. A DOMAIN's
    // bytes may be in a file instead (CiA 306 UploadFile / DownloadFile), as hex in the value otherwise.
    const IniKey* dv = s.find("parametervalue");
    const IniKey* file = nullptr;
    if (dv == nullptr && e.data_type == DataType::Domain) {
      file = s.find("uploadfile");
      if (file == nullptr) file = s.find("downloadfile");
    }
    if (dv == nullptr && file == nullptr) dv = s.find("defaultvalue");
    std::vector<std::uint8_t> def, low, high;
    if (file != nullptr) {
      e.default_value = domainFile(s, *file);
      e.default_line = file->line;
      e.valued = true;
    } else if (dv != nullptr) {
      e.default_value = std::string(trim(dv->value));
      e.default_line = dv->line;
      e.valued = true;
      check(s, *dv, e.data_type, def);
    } else {
      e.default_line = s.line;
      encodeEdsValue("", e.data_type, 1, def);
    }
    if (const IniKey* k = s.find("lowlimit"); k != nullptr && !trim(k->value).empty()) {
      if (!isNumeric(e.data_type)) fail(s, *k, "limits need a numeric data type");
      e.low_limit = std::string(trim(k->value));
      e.low_line = k->line;
      check(s, *k, e.data_type, low);
    }
    if (const IniKey* k = s.find("highlimit"); k != nullptr && !trim(k->value).empty()) {
      if (!isNumeric(e.data_type)) fail(s, *k, "limits need a numeric data type");
      e.high_limit = std::string(trim(k->value));
      e.high_line = k->line;
      check(s, *k, e.data_type, high);
    }
    bool unordered = false;
    if (!low.empty() && !high.empty() && compareValues(e.data_type, low.data(), high.data(), unordered) > 0) {
      fail(s, *s.find("highlimit"), "HighLimit is below LowLimit");
    }
    // $NODEID values depend on the node-ID, so only literal defaults are range-checked here.
    if (e.default_value.find('$') == std::string::npos && isNumeric(e.data_type)) {
      int line = dv != nullptr ? dv->line : s.line;
      if (!low.empty() && compareValues(e.data_type, def.data(), low.data(), unordered) < 0) {
        fail(line, s.name, "DefaultValue " + quoted(e.default_value) + " is below LowLimit");
      }
      if (!high.empty() && compareValues(e.data_type, def.data(), high.data(), unordered) > 0) {
        fail(line, s.name, "DefaultValue " + quoted(e.default_value) + " is above HighLimit");
      }
    }
  }

  void check(const IniSection& s, const IniKey& k, DataType type, std::vector<std::uint8_t>& out) const {
    std::string err = encodeEdsValue(k.value, type, 1, out);
    if (!err.empty()) fail(s, k, err);
  }

  // The bytes of a DOMAIN's file (relative to this file's folder), as the hex text of a value.
  std::string domainFile(const IniSection& s, const IniKey& k) const {
    const std::string name(trim(k.value));
    if (name.empty()) fail(s, k, "no file named");
    const std::string path = name[0] == '/' ? name : dir_ + name;
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0) fail(s, k, path + ": cannot open file: " + std::strerror(errno));
    if (!S_ISREG(st.st_mode)) fail(s, k, path + ": not a regular file");
    if (st.st_size > kMaxDomainFile) fail(s, k, path + ": larger than " + std::to_string(kMaxDomainFile) + " bytes");
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(s, k, path + ": cannot open file: " + std::strerror(errno));
    std::string hex;
    static const char digits[] = "0123456789ABCDEF";
    for (char c; in.get(c);) {
      const auto b = static_cast<unsigned char>(c);
      hex += digits[b >> 4];
      hex += digits[b & 0xF];
    }
    return hex;
  }

 private:
  std::string file_;
  std::string dir_;
};

// [xxxxName] / [xxxxValue] of a CompactSubObj object (CiA 306): NrOfEntries, then "<sub-index>=<name or
// value>" for the sub-objects that differ from the object's own ParameterName / DefaultValue.
void compactList(const Checker& c, const IniSection& s, EdsObject& obj, bool values) {
  const IniKey& count = c.require(s, "nrofentries", "NrOfEntries");
  const std::uint64_t n = c.number(s, count, 254);
  std::uint64_t seen = 0;
  for (const IniKey& k : s.keys) {
    if (&k == &count) continue;
    std::uint64_t sub = 0;
    if (!parseUnsigned(k.name, sub, 10) || sub == 0 || sub >= obj.subs.size())
      c.fail(s, k, "not a sub-index of the object (1.." + std::to_string(obj.subs.size() - 1) + ")");
    EdsSubObject& e = obj.subs[sub];
    ++seen;
    if (!values) {
      e.name = k.value;
      continue;
    }
    e.default_value = std::string(trim(k.value));
    e.default_line = k.line;
    e.valued = true;
    std::vector<std::uint8_t> bytes;
    c.check(s, k, e.data_type, bytes);
  }
  if (seen != n)
    c.fail(s, count, "NrOfEntries is " + std::to_string(n) + " but " + std::to_string(seen) + " entries follow");
}

bool startsWithHex4(const std::string& lname) {
  return lname.size() >= 4 && isHex(std::string_view(lname).substr(0, 4));
}

void buildFile(const IniFile& ini, EdsFile& eds) {
  Checker c(ini.path);
  // Sections in file order, so the first problem reported is the first one in the file.
  std::vector<const IniSection*> order;
  for (const auto& sec : ini.sections) order.push_back(&sec);
  auto section = [&](const char* name) { return ini.find(name); };
  const IniSection* fi = section("fileinfo");
  if (fi == nullptr) c.fail(0, "FileInfo", "missing section [FileInfo]");
  const IniSection* di = section("deviceinfo");
  if (di == nullptr) c.fail(0, "DeviceInfo", "missing section [DeviceInfo]");
  for (const auto& k : fi->keys) eds.file_info[lower(k.name)] = k.value;
  for (const auto& k : di->keys) eds.device_info[lower(k.name)] = k.value;
  if (const IniSection* dc = section("devicecomissioning")) {
    if (const IniKey* k = dc->find("nodeid")) {
      std::uint64_t id = c.number(*dc, *k, 127);
      if (id == 0) c.fail(*dc, *k, "node-ID must be 1..127");
      eds.node_id = static_cast<std::uint8_t>(id);
    }
  }

  // Object sections.
  std::map<std::uint16_t, const IniSection*> object_sections;
  std::map<std::uint16_t, std::map<std::uint8_t, const IniSection*>> sub_sections;
  std::map<std::uint16_t, const IniSection*> name_sections, value_sections;  // of CompactSubObj objects
  for (const IniSection* s : order) {
    std::string ln = lower(s->name);
    if (!startsWithHex4(ln)) continue;
    auto index = static_cast<std::uint16_t>(std::strtoul(ln.substr(0, 4).c_str(), nullptr, 16));
    std::string rest = ln.substr(4);
    if (rest.empty()) {
      object_sections[index] = s;
    } else if (rest.compare(0, 3, "sub") == 0 && rest.size() <= 5 && isHex(std::string_view(rest).substr(3))) {
      auto sub = static_cast<std::uint8_t>(std::strtoul(rest.substr(3).c_str(), nullptr, 16));
      sub_sections[index][sub] = s;
    } else if (rest == "name" || rest == "value") {
      (rest == "name" ? name_sections : value_sections)[index] = s;
    } else if (rest != "objectlinks") {
      c.fail(*s, "section name is neither an object [xxxx] nor a sub-object [xxxxsubN]");
    }
  }
  for (const auto& kv : sub_sections) {
    if (object_sections.count(kv.first) == 0) {
      c.fail(*kv.second.begin()->second, "sub-object of an object that has no section");
    }
  }
  for (const auto* list : {&name_sections, &value_sections}) {
    for (const auto& kv : *list) {
      const IniKey* compact =
          object_sections.count(kv.first) ? object_sections[kv.first]->find("compactsubobj") : nullptr;
      if (compact == nullptr) c.fail(*kv.second, "names or values of sub-objects need an object with CompactSubObj");
    }
  }

  for (const auto& kv : object_sections) {
    const IniSection& s = *kv.second;
    EdsObject obj;
    obj.index = kv.first;
    obj.line = s.line;
    obj.name = c.require(s, "parametername", "ParameterName").value;
    std::uint64_t ot = 0x7;
    if (const IniKey* k = s.find("objecttype")) ot = c.number(s, *k, 0xFF);
    if (ot == 0x5 || ot == 0x6) continue;  // DEFTYPE/DEFSTRUCT only describe types, they hold no data
    bool has_subs = sub_sections.count(obj.index) != 0;
    if (ot == 0x7 || ot == 0x2) {
      obj.object_type = ObjectType::Var;
      if (has_subs) c.fail(s, "a VAR object cannot have sub-object sections");
      EdsSubObject e;
      c.readEntry(s, e);
      if (ot == 0x2 && e.data_type != DataType::Domain) c.fail(s, "ObjectType 0x2 (DOMAIN) needs DataType 0x000F");
      obj.subs.push_back(std::move(e));
    } else if (ot == 0x8 || ot == 0x9) {
      obj.object_type = ot == 0x8 ? ObjectType::Array : ObjectType::Record;
      const IniKey* compact = s.find("compactsubobj");
      if (compact != nullptr && c.number(s, *compact, 254) != 0) {
        if (has_subs) c.fail(s, "CompactSubObj and sub-object sections exclude each other");
        auto n = static_cast<std::uint8_t>(c.number(s, *compact, 254));
        EdsSubObject sub0;
        sub0.section = s.name;
        sub0.line = s.line;
        sub0.name = "Highest sub-index supported";
        sub0.data_type = DataType::Unsigned8;
        sub0.access = Access::ReadOnly;
        sub0.default_value = std::to_string(n);
        sub0.default_line = compact->line;
        obj.subs.push_back(sub0);
        EdsSubObject proto;
        c.readEntry(s, proto);
        for (unsigned i = 1; i <= n; ++i) {
          EdsSubObject e = proto;
          e.sub_index = static_cast<std::uint8_t>(i);
          e.name = proto.name + " " + std::to_string(i);
          obj.subs.push_back(e);
        }
        if (auto it = name_sections.find(obj.index); it != name_sections.end()) compactList(c, *it->second, obj, false);
        if (auto it = value_sections.find(obj.index); it != value_sections.end())
          compactList(c, *it->second, obj, true);
      } else {
        const IniKey& sn = c.require(s, "subnumber", "SubNumber");
        std::uint64_t count = c.number(s, sn, 255);
        auto it = sub_sections.find(obj.index);
        std::size_t present = it == sub_sections.end() ? 0 : it->second.size();
        if (count != present) {
          c.fail(s, sn,
                 "SubNumber is " + std::to_string(count) + " but " + std::to_string(present) +
                     " sub-object sections exist");
        }
        if (present == 0 || it->second.begin()->first != 0)
          c.fail(s, "missing sub-object section [" + s.name + "sub0]");
        for (const auto& sk : it->second) {
          EdsSubObject e;
          e.sub_index = sk.first;
          c.readEntry(*sk.second, e);
          if (sk.first == 0 && e.data_type != DataType::Unsigned8) {
            c.fail(*sk.second, "sub-index 0 of an ARRAY/RECORD must be UNSIGNED8");
          }
          obj.subs.push_back(std::move(e));
        }
      }
    } else {
      c.fail(s, *s.find("objecttype"),
             quoted(s.find("objecttype")->value) + " is not a supported ObjectType (0x7 VAR, 0x8 ARRAY, 0x9 RECORD)");
    }
    eds.objects.push_back(std::move(obj));
  }

  // Object lists: every object must be listed exactly once, every listed object must exist.
  std::set<std::uint16_t> listed;
  bool any_list = false;
  for (const char* list : {"mandatoryobjects", "optionalobjects", "manufacturerobjects"}) {
    const IniSection* s = section(list);
    if (s == nullptr) continue;
    any_list = true;
    const IniKey& so = c.require(*s, "supportedobjects", "SupportedObjects");
    std::uint64_t n = c.number(*s, so, 0xFFFF);
    for (std::uint64_t i = 1; i <= n; ++i) {
      std::string key = std::to_string(i);
      const IniKey* k = s->find(key.c_str());
      if (k == nullptr) c.fail(*s, "SupportedObjects is " + std::to_string(n) + " but key " + key + " is missing");
      auto idx = static_cast<std::uint16_t>(c.number(*s, *k, 0xFFFF));
      if (!listed.insert(idx).second) c.fail(*s, *k, "object listed twice");
      if (object_sections.count(idx) == 0) c.fail(*s, *k, "listed object has no section");
    }
  }
  if (!any_list || section("mandatoryobjects") == nullptr) {
    c.fail(0, "MandatoryObjects", "missing section [MandatoryObjects]");
  }
  for (const auto& kv : object_sections) {
    if (listed.count(kv.first) == 0) {
      c.fail(*kv.second, "object is not listed in [MandatoryObjects], [OptionalObjects] or [ManufacturerObjects]");
    }
  }
  for (std::uint16_t mandatory : {0x1000, 0x1001, 0x1018}) {
    if (object_sections.count(mandatory) == 0) {
      char buf[48];
      std::snprintf(buf, sizeof buf, "mandatory object %04X is missing", static_cast<unsigned>(mandatory));
      c.fail(section("mandatoryobjects")->line, "MandatoryObjects", buf);
    }
  }
}

template <class T>
void append(std::vector<std::uint8_t>& out, T v) {
  std::uint8_t b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  out.insert(out.end(), b, b + sizeof(T));
}

}  // namespace

EdsError::EdsError(std::string file, int line, std::string section, std::string problem)
    : std::runtime_error(file + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " +
                         (section.empty() ? std::string() : "[" + section + "] ") + problem),
      file_(std::move(file)),
      line_(line),
      section_(std::move(section)),
      problem_(std::move(problem)) {}

EdsFile EdsFile::load(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw EdsError(path, 0, "", std::string("cannot open file: ") + std::strerror(errno));
  std::ostringstream ss;
  ss << in.rdbuf();
  return parse(ss.str(), path);
}

EdsFile EdsFile::parse(const std::string& text, const std::string& name) {
  IniFile ini;
  try {
    ini = parseIni(text, name);
  } catch (const IniError& e) {
    throw EdsError(name, e.line(), "", e.problem());
  }
  EdsFile eds;
  eds.file = name;
  buildFile(ini, eds);
  return eds;
}

const EdsObject* EdsFile::find(std::uint16_t index) const {
  auto it = std::lower_bound(objects.begin(), objects.end(), index,
                             [](const EdsObject& o, std::uint16_t v) { return o.index < v; });
  return it == objects.end() || it->index != index ? nullptr : &*it;
}

std::string encodeEdsValue(std::string_view raw, DataType type, std::uint8_t node_id, std::vector<std::uint8_t>& out) {
  out.clear();
  std::string_view text = trim(raw);
  const char* tname = dataTypeName(type);
  switch (type) {
    case DataType::VisibleString: out.assign(text.begin(), text.end()); return "";
    case DataType::OctetString:
    case DataType::Domain: {
      std::string hex;
      for (char ch : text) {
        if (std::isspace(static_cast<unsigned char>(ch))) continue;
        hex.push_back(ch);
      }
      if (hex.size() % 2 != 0 || (!hex.empty() && !isHex(hex))) {
        return quoted(text) + " is not a sequence of hex bytes for " + tname;
      }
      for (std::size_t i = 0; i < hex.size(); i += 2) {
        out.push_back(static_cast<std::uint8_t>(std::strtoul(hex.substr(i, 2).c_str(), nullptr, 16)));
      }
      return "";
    }
    case DataType::Real32:
    case DataType::Real64: {
      double v = 0.0;
      if (!text.empty()) {
        std::string s(text);
        char* end = nullptr;
        errno = 0;
        v = std::strtod(s.c_str(), &end);
        if (end == s.c_str() || *end != '\0') return quoted(text) + " is not a valid " + tname + " value";
        if (errno == ERANGE && std::isinf(v)) return quoted(text) + " is out of range for " + tname;
      }
      if (type == DataType::Real32) {
        if (std::isfinite(v) && std::fabs(v) > FLT_MAX) return quoted(text) + " is out of range for REAL32";
        append(out, static_cast<float>(v));
      } else {
        append(out, v);
      }
      return "";
    }
    default: break;
  }

  // Integers: "<number>", "$NODEID", "$NODEID+<number>" or "<number>+$NODEID".
  bool negative = false;
  bool hex_literal = false;
  std::uint64_t magnitude = 0;
  bool has_node = false;
  bool has_number = false;
  std::string_view rest = text;
  while (!rest.empty()) {
    std::size_t plus = rest.find('+');
    std::string_view term = trim(rest.substr(0, plus));
    rest = plus == std::string_view::npos ? std::string_view() : rest.substr(plus + 1);
    if (term.empty()) return quoted(text) + " is not a valid " + tname + " value";
    if (lower(term) == "$nodeid") {
      if (has_node) return quoted(text) + " uses $NODEID twice";
      has_node = true;
      continue;
    }
    if (has_number) return quoted(text) + " has more than one number";
    has_number = true;
    if (term.front() == '-') {
      negative = true;
      term.remove_prefix(1);
    }
    std::string lt = lower(term);
    hex_literal = lt.compare(0, 2, "0x") == 0;
    if (!parseUnsigned(term, magnitude)) return quoted(text) + " is not a valid " + tname + " value";
    if (plus != std::string_view::npos && rest.empty()) return quoted(text) + " ends with '+'";
  }
  std::uint64_t add = has_node ? node_id : 0;
  std::uint64_t bits = 0;  // two's complement 64-bit result
  bool value_negative = false;
  if (negative && magnitude != 0) {
    if (magnitude > (std::uint64_t{1} << 63)) return quoted(text) + " is out of range for " + tname;
    std::int64_t v = static_cast<std::int64_t>(0 - magnitude) + static_cast<std::int64_t>(add);
    value_negative = v < 0;
    bits = static_cast<std::uint64_t>(v);
  } else {
    if (magnitude > std::numeric_limits<std::uint64_t>::max() - add) return quoted(text) + " is out of range";
    bits = magnitude + add;
  }

  std::size_t size = dataTypeSize(type);
  unsigned width = static_cast<unsigned>(size * 8);
  bool is_signed = type == DataType::Integer8 || type == DataType::Integer16 || type == DataType::Integer32 ||
                   type == DataType::Integer64;
  bool ok = true;
  if (type == DataType::Boolean) {
    ok = !value_negative && bits <= 1;
  } else if (is_signed) {
    if (width < 64) {
      auto v = static_cast<std::int64_t>(bits);
      std::int64_t lo = -(std::int64_t{1} << (width - 1));
      std::int64_t hi = (std::int64_t{1} << (width - 1)) - 1;
      // A hex literal may give the raw bit pattern of a negative value, e.g. 0xFFFF for INTEGER16 -1.
      std::int64_t raw_hi = hex_literal && !value_negative ? (std::int64_t{1} << width) - 1 : hi;
      ok = v >= lo && v <= raw_hi;
    } else {
      ok =
          value_negative || bits <= static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()) || hex_literal;
    }
  } else {
    ok = !value_negative && (width == 64 || bits < (std::uint64_t{1} << width));
  }
  if (!ok) return quoted(text) + " is out of range for " + tname;
  for (std::size_t i = 0; i < size; ++i) out.push_back(static_cast<std::uint8_t>(bits >> (8 * i)));
  return "";
}

}  // namespace pamc::canopen
