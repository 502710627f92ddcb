#include "nodes/rig_file.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <cstdio>
#include <set>
#include <stdexcept>
#include <vector>

#include "canopen/eds_dictionary.hpp"
#include "canopen/ini.hpp"
#include "canopen/od.hpp"
#include "control/controller.hpp"
#include "control/trajectory.hpp"
#include "io/model_file.hpp"

namespace pamc::nodes {

using canopen::ConciseDcf;
using canopen::dcfValue;
using canopen::IniKey;
using canopen::IniSection;
using canopen::ObjectDictionary;

namespace {

std::string hex(std::uint32_t v, int digits) {
  char b[16];
  std::snprintf(b, sizeof b, "0x%0*X", digits, v);
  return b;
}
std::string objName(std::uint16_t index, std::uint8_t sub) { return hex(index, 4) + ":" + hex(sub, 2).substr(2); }

// Keys each section takes (one table: a typo is an error, not a silently ignored setting).
const std::set<std::string> kBusKeys = {"interface", "bitrate", "period_us"};
const std::set<std::string> kControllerKeys = {"node_id", "eds", "startup", "boot_time_ms", "faults"};
const std::set<std::string> kSlaveCommon = {
    "node_id",   "eds",        "device_type",  "vendor_id",           "product_code",
    "revision",  "serial",     "heartbeat_ms", "master_heartbeat_ms", "boot",
    "mandatory", "keep_alive", "retries"};
const std::set<std::string> kSensorKeys = {"position", "position_step_mm", "tpdo", "cob_id"};
const std::set<std::string> kValveKeys = {
    "command",  "command_full_counts",  "command_zero_counts", "rpdo",           "cob_id",
    "feedback", "feedback_full_counts", "feedback_tpdo",       "feedback_cob_id"};
// [slave.NAME]: the slave keys of both kinds but the objects, which the channels name.
const std::set<std::string> kSlaveKeys = {
    "position_step_mm",     "tpdo",          "cob_id",         "command_full_counts", "command_zero_counts", "rpdo",
    "feedback_full_counts", "feedback_tpdo", "feedback_cob_id"};
const std::set<std::string> kChannelKeys = {"sensor",  "position",   "valve", "command",   "feedback",
                                            "partner", "controller", "model", "trajectory"};
const std::set<std::string> kJointKeys = {"muscles",  "sensor",  "angle",       "angle_step_deg", "angle_zero_counts",
                                          "lever_mm", "rest_mm", "stiffness_v", "trajectory"};

class Reader {
 public:
  explicit Reader(const canopen::IniFile& ini) : ini_(ini) {
    const auto slash = ini.path.find_last_of('/');
    dir_ = slash == std::string::npos ? std::string() : ini.path.substr(0, slash + 1);
  }
  [[noreturn]] void fail(int line, const std::string& problem) const {
    throw RigError(ini_.path + (line > 0 ? ":" + std::to_string(line) : std::string()) + ": " + problem);
  }
  const IniSection& need(const char* name) const {
    const IniSection* s = ini_.find(name);
    if (s == nullptr) fail(0, std::string("no [") + name + "] section");
    return *s;
  }
  void knownKeys(const IniSection& s, const std::set<std::string>& a, const std::set<std::string>& b = {}) const {
    for (const auto& k : s.keys) {
      std::string n = k.name;
      std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
      if (n == "reset")  // the key of the former reading of 0x1F81 bit 4
        fail(k.line,
             "reset: 0x1F81 bit 4 is keep alive (CiA 302-2); a slave back after a heartbeat loss is reset "
             "unless keep_alive = yes");
      if (a.count(n) == 0 && b.count(n) == 0) fail(k.line, "unknown key '" + k.name + "' in [" + s.name + "]");
    }
  }
  std::uint64_t unsignedKey(const IniSection& s, const char* key, std::uint64_t def, std::uint64_t lo,
                            std::uint64_t hi) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) return def;
    std::uint64_t v = 0;
    if (!canopen::parseIniUnsigned(k->value, v))
      fail(k->line, std::string(key) + " '" + k->value + "' is not a number");
    if (v < lo || v > hi)
      fail(k->line,
           std::string(key) + " " + k->value + " is outside " + std::to_string(lo) + ".." + std::to_string(hi));
    return v;
  }
  std::optional<std::uint32_t> optionalU32(const IniSection& s, const char* key) const {
    if (s.find(key) == nullptr) return std::nullopt;
    return static_cast<std::uint32_t>(unsignedKey(s, key, 0, 0, 0xFFFFFFFFu));
  }
  double doubleKey(const IniSection& s, const char* key, double def, double lo, double hi) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) return def;
    double v = 0;
    if (!canopen::parseIniDouble(k->value, v)) fail(k->line, std::string(key) + " '" + k->value + "' is not a number");
    if (v < lo || v > hi) fail(k->line, std::string(key) + " " + k->value + " is outside " + fmt(lo) + ".." + fmt(hi));
    return v;
  }
  bool boolKey(const IniSection& s, const char* key, bool def) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) return def;
    if (k->value == "yes" || k->value == "true" || k->value == "1") return true;
    if (k->value == "no" || k->value == "false" || k->value == "0") return false;
    fail(k->line, std::string(key) + " '" + k->value + "' is not yes or no");
  }
  std::string pathKey(const IniSection& s, const char* key) const {
    const IniKey* k = s.find(key);
    if (k == nullptr || k->value.empty()) fail(s.line, std::string("[") + s.name + "] needs " + key);
    const std::string p = k->value[0] == '/' ? k->value : dir_ + k->value;
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0) fail(k->line, std::string(key) + " " + p + ": cannot open file");
    if (!S_ISREG(st.st_mode)) fail(k->line, std::string(key) + " " + p + ": not a regular file");
    return p;
  }
  // "0x6004:00" (index and sub-index in hex).
  std::pair<std::uint16_t, std::uint8_t> object(const IniKey& k) const {
    const auto colon = k.value.find(':');
    std::uint64_t idx = 0, sub = 0;
    if (colon == std::string::npos || !canopen::parseIniUnsigned(k.value.substr(0, colon), idx) ||
        !canopen::parseIniUnsigned("0x" + k.value.substr(colon + 1), sub) || idx == 0 || idx > 0xFFFF || sub > 0xFF)
      fail(k.line, k.name + " '" + k.value + "' is not an object (write 0xINDEX:SUB, e.g. 0x6004:00)");
    return {static_cast<std::uint16_t>(idx), static_cast<std::uint8_t>(sub)};
  }
  // An [x.sdo] key in the EDS's own notation: "6200" (sub-index 0) or "6411sub1" (hex; an INI key
  // cannot hold ':').
  std::pair<std::uint16_t, std::uint8_t> entryName(const IniKey& k) const {
    std::string n = k.name;
    std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (n.rfind("0x", 0) == 0) n.erase(0, 2);
    const auto at = n.find("sub");
    std::uint64_t idx = 0, sub = 0;
    const bool ok = canopen::parseIniUnsigned("0x" + n.substr(0, at), idx) &&
                    (at == std::string::npos || canopen::parseIniUnsigned("0x" + n.substr(at + 3), sub));
    if (!ok || idx == 0 || idx > 0xFFFF || sub > 0xFF)
      fail(k.line, "'" + k.name + "' is not an entry (write it as the EDS does: 6200 or 6411sub1)");
    return {static_cast<std::uint16_t>(idx), static_cast<std::uint8_t>(sub)};
  }
  const IniKey& needKey(const IniSection& s, const char* key) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) fail(s.line, std::string("[") + s.name + "] needs " + key);
    return *k;
  }

 private:
  static std::string fmt(double v) {
    char b[32];
    std::snprintf(b, sizeof b, "%g", v);
    return b;
  }
  const canopen::IniFile& ini_;
  std::string dir_;
};

// One slave while its boot is put together.
struct SlaveBuild {
  const IniSection* sec;
  std::string name;
  std::uint8_t id;
  std::string eds;
  ObjectDictionary od;
  canopen::SlaveBoot boot;
  unsigned heartbeat_ms = 0;
};

const canopen::Entry& entry(const Reader& r, const SlaveBuild& s, int line, std::uint16_t index, std::uint8_t sub) {
  const canopen::Entry* e = s.od.find(index, sub);
  if (e == nullptr) r.fail(line, s.eds + " has no object " + objName(index, sub));
  return *e;
}

std::uint32_t mappingValue(const canopen::Entry& e) {
  return (static_cast<std::uint32_t>(e.index()) << 16) | (static_cast<std::uint32_t>(e.subIndex()) << 8) |
         static_cast<std::uint32_t>(e.size() * 8);
}

// A PDO of the slave set up for the cycle: disabled, synchronous, mapped to `mapped` in order (at most
// 8 bytes), enabled on cob.
void pdoWrites(const Reader& r, SlaveBuild& s, int line, bool transmit, unsigned n, std::uint32_t cob,
               const std::vector<const canopen::Entry*>& mapped) {
  const std::uint16_t comm = static_cast<std::uint16_t>((transmit ? 0x1800 : 0x1400) + n - 1);
  const std::uint16_t map = static_cast<std::uint16_t>((transmit ? 0x1A00 : 0x1600) + n - 1);
  const char* what = transmit ? "TPDO" : "RPDO";
  if (s.od.find(comm, 1) == nullptr || s.od.find(comm, 2) == nullptr || s.od.find(map, 0) == nullptr ||
      s.od.find(map, 1) == nullptr)
    r.fail(line, s.eds + " has no " + what + " " + std::to_string(n) + " (" + hex(comm, 4) + " / " + hex(map, 4) + ")");
  std::size_t bytes = 0;
  for (const canopen::Entry* e : mapped) {
    if (!e->pdoMappable())
      r.fail(line, s.eds + ": " + objName(e->index(), e->subIndex()) + " cannot be mapped into a PDO");
    bytes += e->size();
  }
  if (bytes > 8)
    r.fail(line, s.eds + ": " + std::to_string(mapped.size()) + " channels need " + std::to_string(bytes) +
                     " bytes in " + what + " " + std::to_string(n) + ", a PDO carries 8");
  for (std::size_t i = 1; i <= mapped.size(); ++i)
    if (s.od.find(map, static_cast<std::uint8_t>(i)) == nullptr)
      r.fail(line, s.eds + ": " + what + " " + std::to_string(n) + " maps fewer than " + std::to_string(mapped.size()) +
                       " objects");
  auto& w = s.boot.writes;
  w.push_back(dcfValue(comm, 1, cob | 0x80000000u, 4));  // CiA 301: change a PDO only while it is disabled
  w.push_back(dcfValue(comm, 2, 1, 1));                  // synchronous, every SYNC
  if (const auto* et = s.od.find(comm, 5); et != nullptr && et->writable()) w.push_back(dcfValue(comm, 5, 0, 2));
  w.push_back(dcfValue(map, 0, 0, 1));
  for (std::size_t i = 0; i < mapped.size(); ++i)
    w.push_back(dcfValue(map, static_cast<std::uint8_t>(i + 1), mappingValue(*mapped[i]), 4));
  w.push_back(dcfValue(map, 0, mapped.size(), 1));
  w.push_back(dcfValue(comm, 1, cob, 4));
}

// Every other TPDO of the slave off: asynchronous defaults would load the bus, and might use a COB-ID
// of the cycle.
void otherTpdosOff(SlaveBuild& s, unsigned keep) {
  for (unsigned n = 1; n <= 512; ++n) {
    if (n == keep) continue;
    const auto comm = static_cast<std::uint16_t>(0x1800 + n - 1);
    const canopen::Entry* cob = s.od.find(comm, 1);
    if (cob == nullptr) continue;
    s.boot.writes.push_back(dcfValue(comm, 1, (cob->get<std::uint32_t>() & 0x1FFFFFFFu) | 0x80000000u, 4));
  }
}

std::uint32_t defaultPdoCob(const Reader& r, int line, bool transmit, unsigned n, std::uint8_t id) {
  if (n > 4) r.fail(line, "PDO " + std::to_string(n) + " has no predefined COB-ID: give cob_id");
  return static_cast<std::uint32_t>((transmit ? 0x180 : 0x200) + 0x100 * (n - 1) + id);
}

SlaveBuild slaveCommon(const Reader& r, const IniSection& sec, std::uint8_t controller_id) {
  SlaveBuild s{&sec, {}, 0, {}, ObjectDictionary({}, {}), {}, 0};
  s.id = static_cast<std::uint8_t>(r.unsignedKey(sec, "node_id", 0, 1, 127));
  if (sec.find("node_id") == nullptr) r.fail(sec.line, "[" + sec.name + "] needs node_id");
  s.eds = r.pathKey(sec, "eds");
  s.od = canopen::loadDictionary(s.eds, s.id);
  s.boot.device_type = r.optionalU32(sec, "device_type");
  s.boot.vendor_id = r.optionalU32(sec, "vendor_id");
  s.boot.product_code = r.optionalU32(sec, "product_code");
  s.boot.revision = r.optionalU32(sec, "revision");
  s.boot.serial = r.optionalU32(sec, "serial");
  std::uint32_t a = canopen::kAssignSlave;
  if (r.boolKey(sec, "boot", true)) a |= canopen::kAssignBoot;
  if (r.boolKey(sec, "mandatory", true)) a |= canopen::kAssignMandatory;
  if (r.boolKey(sec, "keep_alive", false)) a |= canopen::kAssignKeepAlive;
  a |= canopen::assignRetries(static_cast<unsigned>(r.unsignedKey(sec, "retries", 3, 0, 255)));
  s.boot.assignment = a;
  (void)controller_id;
  return s;
}

// Heartbeats and the extra writes of [<role>.sdo]; they follow the PDOs.
void slaveTail(const Reader& r, const canopen::IniFile& ini, SlaveBuild& s, std::uint8_t controller_id) {
  const IniSection& sec = *s.sec;
  if (const IniKey* k = sec.find("heartbeat_ms")) {
    const auto ms = r.unsignedKey(sec, "heartbeat_ms", 0, 0, 0xFFFF);
    entry(r, s, k->line, 0x1017, 0);
    s.boot.writes.push_back(dcfValue(0x1017, 0, ms, 2));
    s.heartbeat_ms = static_cast<unsigned>(ms);
  } else if (const canopen::Entry* e = s.od.find(0x1017, 0)) {
    s.heartbeat_ms = static_cast<unsigned>(e->asUnsigned());  // what it produces by itself
  }
  if (const IniKey* k = sec.find("master_heartbeat_ms")) {
    const auto ms = r.unsignedKey(sec, "master_heartbeat_ms", 0, 1, 0xFFFF);
    entry(r, s, k->line, 0x1016, 1);
    s.boot.writes.push_back(dcfValue(0x1016, 1, (static_cast<std::uint32_t>(controller_id) << 16) | ms, 4));
  }
  if (const IniSection* extra = ini.find(sec.name + ".sdo")) {
    for (const auto& k : extra->keys) {
      const auto [index, sub] = r.entryName(k);
      const canopen::Entry& e = entry(r, s, k.line, index, sub);
      if (!e.writable()) r.fail(k.line, s.eds + ": " + objName(index, sub) + " is read-only");
      canopen::DcfEntry d{index, sub, {}};
      const std::string problem = canopen::encodeEdsValue(k.value, e.dataType(), s.id, d.data);
      if (!problem.empty()) r.fail(k.line, k.name + ": " + problem);
      s.boot.writes.push_back(std::move(d));
    }
  }
}

}  // namespace

namespace {
RigFile fromIni(const canopen::IniFile& ini);
}

RigFile readRigFile(const std::string& path) {
  try {
    return fromIni(canopen::readIni(path));
  } catch (const canopen::IniError& e) {
    throw RigError(e.what());
  }
}

RigFile parseRigFile(const std::string& text, const std::string& path) {
  try {
    return fromIni(canopen::parseIni(text, path));
  } catch (const canopen::IniError& e) {
    throw RigError(e.what());
  }
}

namespace {

// One channel while the file is read: its slaves (indices into the builds), its objects in them.
struct ChannelBuild {
  int line = 0;
  std::size_t index = 0;
  bool joint_scaling = false;  // a joint's muscle: its position from the angle (step and offset below)
  double step_mm = 0.0, offset_mm = 0.0;
  std::size_t sensor = 0, valve = 0;
  const canopen::Entry* position = nullptr;
  const canopen::Entry* command = nullptr;
  const canopen::Entry* feedback = nullptr;  // none
  RigChannel out;
};

struct FileBuild {
  std::vector<SlaveBuild> slaves;
  std::vector<ChannelBuild> channels;
  std::vector<RigJoint> joints;
  std::vector<const IniSection*> joint_sections;
  std::vector<const canopen::Entry*> joint_angles;
};

std::string lower(std::string n) {
  std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return n;
}

void readBusAndController(const Reader& r, const canopen::IniFile& ini, RigFile& rig) {
  if (const IniSection* bus = ini.find("bus")) {
    r.knownKeys(*bus, kBusKeys);
    if (const IniKey* k = bus->find("interface")) rig.interface = k->value;
    rig.bitrate = static_cast<unsigned>(r.unsignedKey(*bus, "bitrate", rig.bitrate, 10000, 1000000));
    rig.period_us = static_cast<unsigned>(r.unsignedKey(*bus, "period_us", rig.period_us, 100, 1000000));
  }
  const IniSection& ctl = r.need("controller");
  r.knownKeys(ctl, kControllerKeys);
  rig.controller_id = static_cast<std::uint8_t>(r.unsignedKey(ctl, "node_id", 1, 1, 127));
  rig.controller_eds = r.pathKey(ctl, "eds");
  rig.startup = static_cast<std::uint32_t>(r.unsignedKey(ctl, "startup", canopen::kStartupMaster, 0, 0xFFFFFFFFu));
  if ((rig.startup & ~canopen::kStartupSupported) != 0)
    r.fail(ctl.find("startup")->line, "startup " + hex(rig.startup, 8) + ": only bits 0-3 of 0x1F80 are implemented");
  rig.boot_time_ms = static_cast<unsigned>(r.unsignedKey(ctl, "boot_time_ms", 0, 0, 0xFFFFFFFFu));
  if (const IniKey* k = ctl.find("faults")) {
    if (k->value != "channel" && k->value != "all") r.fail(k->line, "faults '" + k->value + "' is not channel or all");
    rig.fault_all = k->value == "all";
  }
}

// A channel's object in its slave: where the key names it, checked for what the controller carries.
const canopen::Entry& channelObject(const Reader& r, const SlaveBuild& s, const IniKey& k, const char* what) {
  const auto [idx, sub] = r.object(k);
  const canopen::Entry& e = entry(r, s, k.line, idx, sub);
  const std::string name = s.eds + ": " + objName(idx, sub);
  if (std::string(what) == "position" && (e.size() != 4 || !(e.dataType() == canopen::DataType::Integer32 ||
                                                             e.dataType() == canopen::DataType::Unsigned32)))
    r.fail(k.line, name + " is not 32 bits: the controller takes 32-bit positions");
  if (std::string(what) == "command" && (e.size() != 2 || !e.writable()))
    r.fail(k.line, name + " is not a writable 16-bit object: the controller sends 16-bit commands");
  if (std::string(what) == "feedback" && e.size() != 2)
    r.fail(k.line, name + " is not 16 bits: the controller takes 16-bit feedback");
  return e;
}

// The one-muscle form: [sensor] with the position, [valve] with the command and the feedback.
void readOneMuscle(const Reader& r, RigFile& rig, FileBuild& fb) {
  const IniSection& ss = r.need("sensor");
  r.knownKeys(ss, kSlaveCommon, kSensorKeys);
  fb.slaves.push_back(slaveCommon(r, ss, rig.controller_id));
  fb.slaves.back().name = "sensor";
  const IniSection& vs = r.need("valve");
  r.knownKeys(vs, kSlaveCommon, kValveKeys);
  fb.slaves.push_back(slaveCommon(r, vs, rig.controller_id));
  fb.slaves.back().name = "valve";
  ChannelBuild c;
  c.sensor = 0, c.valve = 1;
  const IniKey& pos = r.needKey(ss, "position");
  c.line = pos.line;
  c.position = &channelObject(r, fb.slaves[0], pos, "position");
  c.command = &channelObject(r, fb.slaves[1], r.needKey(vs, "command"), "command");
  if (const IniKey* k = vs.find("feedback")) c.feedback = &channelObject(r, fb.slaves[1], *k, "feedback");
  fb.channels.push_back(std::move(c));
}

std::size_t slaveNamed(const Reader& r, const FileBuild& fb, const IniKey& k) {
  for (std::size_t i = 0; i < fb.slaves.size(); ++i)
    if (fb.slaves[i].name == k.value) return i;
  r.fail(k.line, k.name + " '" + k.value + "': no [slave." + k.value + "] section");
}

// What a channel runs of its own: partner, controller, model, trajectory.
void channelOwn(const Reader& r, const IniSection& sec, std::size_t count, std::size_t c, ChannelConfig& cc,
                const std::string& dir) {
  if (sec.find("partner")) {
    cc.partner = static_cast<int>(r.unsignedKey(sec, "partner", 0, 1, count)) - 1;
    if (cc.partner == static_cast<int>(c))
      r.fail(sec.find("partner")->line, "partner: a channel is not its own partner");
  }
  try {
    if (const IniKey* k = sec.find("controller")) cc.kind = static_cast<int>(control::kindFromString(k->value));
  } catch (const std::exception& e) {
    r.fail(sec.find("controller")->line, std::string("controller: ") + e.what());
  }
  if (const IniKey* k = sec.find("trajectory")) {
    try {
      cc.trajectory = control::Trajectory::parse(k->value);
    } catch (const std::exception& e) {
      r.fail(k->line, std::string("trajectory: ") + e.what());
    }
  }
  if (const IniKey* k = sec.find("model")) {
    const std::string p = !k->value.empty() && k->value[0] == '/' ? k->value : dir + k->value;
    try {
      cc.model = io::readModelFile(p);
    } catch (const std::exception& e) {
      r.fail(k->line, std::string("model: ") + e.what());
    }
  }
}

// The channel numbers of a joint's `muscles = 1, 2` (flexor, extensor).
std::pair<std::size_t, std::size_t> jointMuscles(const Reader& r, const IniKey& k, std::size_t count) {
  unsigned a = 0, b = 0;
  char extra = 0;
  if (std::sscanf(k.value.c_str(), " %u , %u %c", &a, &b, &extra) != 2 || a < 1 || b < 1 || a > count || b > count ||
      a == b)
    r.fail(k.line, "muscles '" + k.value + "' is not two channels (flexor, extensor), e.g. 1, 2");
  return {a - 1, b - 1};
}

// [joint.1] ... [joint.M]: two channels each, their angle encoder and lever.
void readJoints(const Reader& r, const canopen::IniFile& ini, std::size_t count, FileBuild& fb) {
  for (std::size_t j = 1; const IniSection* sec = ini.find("joint." + std::to_string(j)); ++j) {
    r.knownKeys(*sec, kJointKeys);
    RigJoint jt;
    std::tie(jt.flexor, jt.extensor) = jointMuscles(r, r.needKey(*sec, "muscles"), count);
    for (const auto& other : fb.joints)
      for (std::size_t m : {other.flexor, other.extensor})
        if (m == jt.flexor || m == jt.extensor)
          r.fail(sec->find("muscles")->line, "muscles: channel " + std::to_string(m + 1) + " is in two joints");
    const std::size_t sensor = slaveNamed(r, fb, r.needKey(*sec, "sensor"));
    fb.joint_angles.push_back(&channelObject(r, fb.slaves[sensor], r.needKey(*sec, "angle"), "position"));
    jt.sensor_id = fb.slaves[sensor].id;
    jt.angle_step_deg = r.doubleKey(*sec, "angle_step_deg", jt.angle_step_deg, 1e-9, 360.0);
    jt.angle_zero_counts = r.doubleKey(*sec, "angle_zero_counts", 0.0, -2.0e9, 2.0e9);
    jt.lever_mm = r.doubleKey(*sec, "lever_mm", jt.lever_mm, 0.1, 1000.0);
    jt.rest_mm = r.doubleKey(*sec, "rest_mm", jt.rest_mm, 0.0, 1000.0);
    jt.stiffness_v = r.doubleKey(*sec, "stiffness_v", 0.0, 0.0, 10.0);
    fb.joints.push_back(jt);
    fb.joint_sections.push_back(sec);
  }
}

// A joint's muscle takes its position from the joint's angle: contraction = rest + sign x lever x angle
// (the flexor +, the extensor -), its partner is the other muscle, the co-contraction on its command,
// the trajectory the angle in degrees. False for a channel in no joint.
bool jointMuscle(const Reader& r, const IniSection& sec, std::size_t c, const FileBuild& fb, ChannelBuild& b) {
  for (std::size_t j = 0; j < fb.joints.size(); ++j) {
    const RigJoint& jt = fb.joints[j];
    if (c != jt.flexor && c != jt.extensor) continue;
    for (const char* key : {"sensor", "position", "partner", "trajectory"})
      if (const IniKey* k = sec.find(key))
        r.fail(k->line, std::string(key) + ": channel " + std::to_string(c + 1) + " is a muscle of [joint." +
                            std::to_string(j + 1) + "], whose angle and pair say it");
    const double sign = c == jt.flexor ? 1.0 : -1.0;
    const double mm_per_deg = sign * jt.lever_mm * M_PI / 180.0;
    for (std::size_t s = 0; s < fb.slaves.size(); ++s)
      if (fb.slaves[s].id == jt.sensor_id) b.sensor = s;
    b.position = fb.joint_angles[j];
    b.joint_scaling = true;
    b.step_mm = mm_per_deg * jt.angle_step_deg;
    b.offset_mm = jt.rest_mm - b.step_mm * jt.angle_zero_counts;
    ChannelConfig& cc = b.out.cfg;
    cc.partner = static_cast<int>(c == jt.flexor ? jt.extensor : jt.flexor);
    cc.command_offset_v = jt.stiffness_v;
    cc.setpoint_scale = mm_per_deg;
    cc.setpoint_offset = jt.rest_mm;
    if (const IniKey* k = fb.joint_sections[j]->find("trajectory")) {
      try {
        cc.trajectory = control::Trajectory::parse(k->value);
      } catch (const std::exception& e) {
        r.fail(k->line, std::string("trajectory: ") + e.what());
      }
    }
    return true;
  }
  return false;
}

// The form of several muscles: [slave.NAME] sections, then [channel.1] ... [channel.N].
void readSlavesAndChannels(const Reader& r, const canopen::IniFile& ini, RigFile& rig, FileBuild& fb) {
  for (const auto& sec : ini.sections) {
    const std::string n = lower(sec.name);
    if (n.rfind("slave.", 0) != 0 || (n.size() > 4 && n.compare(n.size() - 4, 4, ".sdo") == 0)) continue;
    r.knownKeys(sec, kSlaveCommon, kSlaveKeys);
    fb.slaves.push_back(slaveCommon(r, sec, rig.controller_id));
    fb.slaves.back().name = sec.name.substr(6);
  }
  const auto slash = ini.path.find_last_of('/');
  const std::string dir = slash == std::string::npos ? std::string() : ini.path.substr(0, slash + 1);
  std::size_t count = 0;
  while (ini.find("channel." + std::to_string(count + 1)) != nullptr) ++count;
  if (count == 0) r.fail(0, "no [channel.1] section (or [sensor] and [valve] for one muscle)");
  if (count > kMaxChannels)
    r.fail(0, std::to_string(count) + " channels: the controller runs at most " + std::to_string(kMaxChannels));
  readJoints(r, ini, count, fb);
  for (std::size_t c = 0; c < count; ++c) {
    const IniSection& sec = *ini.find("channel." + std::to_string(c + 1));
    r.knownKeys(sec, kChannelKeys);
    ChannelBuild b;
    b.line = sec.line;
    b.index = c;
    b.valve = slaveNamed(r, fb, r.needKey(sec, "valve"));
    if (!jointMuscle(r, sec, c, fb, b)) {
      b.sensor = slaveNamed(r, fb, r.needKey(sec, "sensor"));
      if (b.sensor == b.valve) r.fail(sec.line, "[" + sec.name + "]: its sensor and valve are one slave");
      b.position = &channelObject(r, fb.slaves[b.sensor], r.needKey(sec, "position"), "position");
    }
    if (b.sensor == b.valve) r.fail(sec.line, "[" + sec.name + "]: its sensor and valve are one slave");
    b.command = &channelObject(r, fb.slaves[b.valve], r.needKey(sec, "command"), "command");
    if (const IniKey* k = sec.find("feedback")) b.feedback = &channelObject(r, fb.slaves[b.valve], *k, "feedback");
    channelOwn(r, sec, count, c, b.out.cfg, dir);
    fb.channels.push_back(std::move(b));
  }
  for (std::size_t c = 0; c < count; ++c) {
    const int p = fb.channels[c].out.cfg.partner;
    if (p >= 0 && fb.channels[static_cast<std::size_t>(p)].out.cfg.partner != static_cast<int>(c))
      r.fail(fb.channels[c].line,
             "partner: channel " + std::to_string(p + 1) + " does not name channel " + std::to_string(c + 1) + " back");
  }
}

std::vector<ChannelBuild*> channelsOf(FileBuild& fb, std::size_t slave, bool as_sensor) {
  std::vector<ChannelBuild*> v;
  for (auto& c : fb.channels)
    if ((as_sensor ? c.sensor : c.valve) == slave) v.push_back(&c);
  return v;
}

// A sensor slave: its channels' positions in one TPDO, its measuring step.
void sensorSlave(const Reader& r, SlaveBuild& s, const std::vector<ChannelBuild*>& chans) {
  const IniSection& ss = *s.sec;
  const unsigned tpdo = static_cast<unsigned>(r.unsignedKey(ss, "tpdo", 1, 1, 512));
  const int tpdo_line = ss.find("tpdo") ? ss.find("tpdo")->line : chans[0]->line;
  const auto cob =
      static_cast<std::uint32_t>(r.unsignedKey(ss, "cob_id", defaultPdoCob(r, tpdo_line, true, tpdo, s.id), 1, 0x7FF));
  // Each object once: the two muscles of a joint read one angle.
  std::vector<const canopen::Entry*> mapped;
  for (const ChannelBuild* c : chans)
    if (std::find(mapped.begin(), mapped.end(), c->position) == mapped.end()) mapped.push_back(c->position);
  otherTpdosOff(s, tpdo);
  pdoWrites(r, s, tpdo_line, true, tpdo, cob, mapped);
  pd::Scaling sc;
  bool from_device = false;
  if (const IniKey* k = ss.find("position_step_mm")) {
    if (k->value == "device") {
      // Read at boot; until then (and for decoding a log) the EDS's default, if it has one.
      const canopen::Entry& step = entry(r, s, k->line, 0x6005, 1);
      if (step.asUnsigned() > 0) sc.position_step_mm = static_cast<double>(step.asUnsigned()) * 1e-6;
      from_device = true;
    } else {
      sc.position_step_mm = r.doubleKey(ss, "position_step_mm", 0, 1e-9, 1e3);
      if (!(sc.position_step_mm > 0)) r.fail(k->line, "position_step_mm must be above 0");
    }
  }
  for (ChannelBuild* c : chans) {
    auto& lay = c->out.cfg.layout;
    c->out.cfg.sensor_id = s.id;
    lay.sensor_cob = cob;
    lay.scaling.position_step_mm = c->joint_scaling ? c->step_mm : sc.position_step_mm;
    lay.scaling.position_offset_mm = c->joint_scaling ? c->offset_mm : 0.0;
    lay.position_step_from_device = from_device && !c->joint_scaling;
    c->out.position = RigObject{c->position->index(), c->position->subIndex(), c->position->dataType()};
    unsigned offset = 0;
    for (const canopen::Entry* e : mapped) {
      if (e == c->position) break;
      offset += static_cast<unsigned>(e->size());
    }
    c->out.position_offset = offset;
    // The first channel reading the object receives it; the others read that channel's object.
    for (const ChannelBuild* first : chans)
      if (first->position == c->position) {
        if (first != c) c->out.cfg.position_object = positionObject(first->index);
        break;
      }
  }
  if (from_device) s.boot.assignment |= canopen::kAssignBoot;  // the step is read at boot
}

// A valve slave: its channels' commands in one RPDO, their error values, their feedback in one TPDO.
// A valve slave's feedback: its channels' pressures in one TPDO, or none (then its TPDOs are off).
void valveFeedback(const Reader& r, SlaveBuild& s, const std::vector<ChannelBuild*>& chans,
                   const std::vector<const canopen::Entry*>& fbs) {
  const IniSection& vs = *s.sec;
  if (fbs.empty()) {
    for (ChannelBuild* c : chans) c->out.cfg.layout.feedback = false;
    otherTpdosOff(s, 0);
    return;
  }
  const unsigned tpdo = static_cast<unsigned>(r.unsignedKey(vs, "feedback_tpdo", 1, 1, 512));
  const int line = vs.find("feedback_tpdo") ? vs.find("feedback_tpdo")->line : chans[0]->line;
  const auto fcob = static_cast<std::uint32_t>(
      r.unsignedKey(vs, "feedback_cob_id", defaultPdoCob(r, line, true, tpdo, s.id), 1, 0x7FF));
  otherTpdosOff(s, tpdo);
  pdoWrites(r, s, line, true, tpdo, fcob, fbs);
  const double full = r.doubleKey(vs, "feedback_full_counts", pd::kAnalogFullScaleCounts, 1, 65535);
  unsigned offset = 0;
  for (ChannelBuild* c : chans) {
    c->out.cfg.layout.feedback_cob = fcob;
    c->out.cfg.layout.scaling.pressure_full_counts = full;
    c->out.feedback = RigObject{c->feedback->index(), c->feedback->subIndex(), c->feedback->dataType()};
    c->out.feedback_offset = offset;
    offset += static_cast<unsigned>(c->feedback->size());
  }
}

void valveSlave(const Reader& r, SlaveBuild& s, const std::vector<ChannelBuild*>& chans) {
  const IniSection& vs = *s.sec;
  const unsigned rpdo = static_cast<unsigned>(r.unsignedKey(vs, "rpdo", 1, 1, 512));
  const int rpdo_line = vs.find("rpdo") ? vs.find("rpdo")->line : chans[0]->line;
  const auto cob =
      static_cast<std::uint32_t>(r.unsignedKey(vs, "cob_id", defaultPdoCob(r, rpdo_line, false, rpdo, s.id), 1, 0x7FF));
  std::vector<const canopen::Entry*> cmds, fbs;
  for (const ChannelBuild* c : chans) {
    cmds.push_back(c->command);
    if (c->feedback) fbs.push_back(c->feedback);
  }
  if (!fbs.empty() && fbs.size() != chans.size())
    r.fail(vs.line, "[" + vs.name + "]: some of its channels have a feedback, some not");
  pdoWrites(r, s, rpdo_line, false, rpdo, cob, cmds);
  pd::Scaling sc;
  sc.command_full_counts = r.doubleKey(vs, "command_full_counts", sc.command_full_counts, 1, 65535);
  sc.command_zero_counts = r.doubleKey(vs, "command_zero_counts", 0.0, -32768, 32767);
  unsigned offset = 0;
  for (ChannelBuild* c : chans) {
    auto& lay = c->out.cfg.layout;
    c->out.cfg.valve_id = s.id;
    lay.valve_cob = cob;
    lay.scaling.command_full_counts = sc.command_full_counts;
    lay.scaling.command_zero_counts = sc.command_zero_counts;
    // CiA 401: output n has its error mode 0x6443:n and error value 0x6444:n.
    const auto cidx = c->command->index();
    const auto csub = c->command->subIndex();
    lay.error_value_index = 0;
    if (cidx == 0x6411 && s.od.find(0x6444, csub) != nullptr) {
      lay.error_value_index = 0x6444;
      lay.error_value_sub = csub;
      if (const auto* mode = s.od.find(0x6443, csub); mode != nullptr && mode->writable())
        s.boot.writes.push_back(
            dcfValue(0x6443, csub, 1, mode->size()));  // output the error value on a communication error
    }
    c->out.command = RigObject{cidx, csub, c->command->dataType()};
    c->out.command_offset = offset;
    offset += static_cast<unsigned>(c->command->size());
  }
  valveFeedback(r, s, chans, fbs);
}

// One node per ID, one producer per COB-ID.
void checkUnique(const Reader& r, const RigFile& rig, const FileBuild& fb) {
  std::set<std::uint8_t> ids = {rig.controller_id};
  for (const auto& s : fb.slaves) {
    if (ids.insert(s.id).second) continue;
    if (rig.one_muscle_form)
      r.fail(fb.slaves[1].sec->find("node_id")->line, "node-IDs of controller, sensor and valve must differ");
    r.fail(s.sec->find("node_id")->line, "node-ID " + std::to_string(s.id) + " of [" + s.sec->name + "] is taken");
  }
  std::vector<std::uint32_t> all;
  std::set<std::size_t> seen_s, seen_v;
  for (const auto& c : fb.channels) {
    const auto& l = c.out.cfg.layout;
    if (seen_s.insert(c.sensor).second) all.push_back(l.sensor_cob);
    if (seen_v.insert(c.valve).second) {
      all.push_back(l.valve_cob);
      if (l.feedback) all.push_back(l.feedback_cob);
    }
  }
  std::set<std::uint32_t> once;
  for (std::uint32_t cob : all)
    if (!once.insert(cob).second) r.fail(0, "two PDOs on COB-ID " + hex(cob, 3));
}

// The controller's PDOs: an RPDO per sensor slave, then one per valve slave's feedback, a TPDO per
// valve slave, numbered in the order the channels name them (one muscle: RPDO1, RPDO2, TPDO1).
void controllerPdos(const Reader& r, RigFile& rig, FileBuild& fb) {
  std::vector<std::size_t> sensors, valves;
  for (const auto& c : fb.channels) {
    if (std::find(sensors.begin(), sensors.end(), c.sensor) == sensors.end()) sensors.push_back(c.sensor);
    if (std::find(valves.begin(), valves.end(), c.valve) == valves.end()) valves.push_back(c.valve);
  }
  unsigned rpdos = 0;
  for (auto& c : fb.channels) {
    c.out.cfg.position_rpdo =
        static_cast<unsigned>(std::find(sensors.begin(), sensors.end(), c.sensor) - sensors.begin()) + 1;
    c.out.cfg.command_tpdo =
        static_cast<unsigned>(std::find(valves.begin(), valves.end(), c.valve) - valves.begin()) + 1;
  }
  rpdos = static_cast<unsigned>(sensors.size());
  for (std::size_t v : valves) {
    bool has = false;
    for (auto& c : fb.channels)
      if (c.valve == v && c.feedback) c.out.cfg.feedback_rpdo = rpdos + 1, has = true;
    if (has) ++rpdos;
  }
  const ObjectDictionary od = canopen::loadDictionary(rig.controller_eds, rig.controller_id);
  unsigned have_r = 0, have_t = 0;
  while (od.find(static_cast<std::uint16_t>(0x1400 + have_r), 1) != nullptr) ++have_r;
  while (od.find(static_cast<std::uint16_t>(0x1800 + have_t), 1) != nullptr) ++have_t;
  if (rpdos > have_r || valves.size() > have_t)
    r.fail(0, rig.controller_eds + " has " + std::to_string(have_r) + " RPDOs and " + std::to_string(have_t) +
                  " TPDOs; the channels need " + std::to_string(rpdos) + " and " + std::to_string(valves.size()));
  rig.controller_rpdos = have_r;
  rig.controller_tpdos = have_t;
}

RigFile fromIni(const canopen::IniFile& ini) {
  const Reader r(ini);
  bool one = false, several = false;
  for (const auto& s : ini.sections) {
    static const std::set<std::string> known = {"bus", "controller", "sensor", "valve", "sensor.sdo", "valve.sdo"};
    const std::string n = lower(s.name);
    const bool named = n.rfind("slave.", 0) == 0 || n.rfind("channel.", 0) == 0 || n.rfind("joint.", 0) == 0;
    if (known.count(n) == 0 && !named)
      r.fail(s.line, "unknown section [" + s.name +
                         "] (known: bus, controller, sensor, valve, sensor.sdo, valve.sdo, slave.NAME, slave.NAME.sdo, "
                         "channel.N, joint.N)");
    one = one || n == "sensor" || n == "valve";
    several = several || named;
  }
  if (one && several) r.fail(0, "[sensor]/[valve] and [slave.*]/[channel.*] together: write one form");
  RigFile rig;
  rig.path = ini.path;
  readBusAndController(r, ini, rig);
  rig.one_muscle_form = !several;
  FileBuild fb;
  if (rig.one_muscle_form)
    readOneMuscle(r, rig, fb);
  else
    readSlavesAndChannels(r, ini, rig, fb);
  for (std::size_t i = 0; i < fb.slaves.size(); ++i) {
    const auto as_sensor = channelsOf(fb, i, true), as_valve = channelsOf(fb, i, false);
    if (!as_sensor.empty() && !as_valve.empty())
      r.fail(fb.slaves[i].sec->line,
             "[" + fb.slaves[i].sec->name + "] is a sensor of one channel and a valve of another");
    if (!as_sensor.empty()) sensorSlave(r, fb.slaves[i], as_sensor);
    if (!as_valve.empty()) valveSlave(r, fb.slaves[i], as_valve);
    slaveTail(r, ini, fb.slaves[i], rig.controller_id);
  }
  checkUnique(r, rig, fb);
  controllerPdos(r, rig, fb);
  for (auto& s : fb.slaves) rig.slaves.push_back(RigSlave{s.name, s.id, s.eds, std::move(s.boot), s.heartbeat_ms});
  for (auto& c : fb.channels) rig.channels.push_back(std::move(c.out));
  rig.joints = fb.joints;
  return rig;
}
}  // namespace

const RigSlave& RigFile::slave(std::uint8_t id) const {
  for (const auto& s : slaves)
    if (s.id == id) return s;
  throw std::out_of_range(path + ": no slave with node-ID " + std::to_string(id));
}

void applyRig(const RigFile& rig, ControllerNodeConfig& cfg) {
  cfg.eds_path = rig.controller_eds;
  cfg.node_id = rig.controller_id;
  cfg.period_us = rig.period_us;
  cfg.channels.clear();
  for (const auto& c : rig.channels) cfg.channels.push_back(c.cfg);
  cfg.fault_all = rig.fault_all;
  cfg.dictionary = masterValues(rig);
}

}  // namespace pamc::nodes

namespace pamc::nodes {

namespace {

// The slaves' entries of the master's dictionary: assignment, identity, concise DCF, the consumer
// heartbeat of each (0x1016:01 the first slave's, :02 the second's, ...).
void slaveValues(const RigFile& rig, canopen::ConciseDcf& v) {
  using canopen::dcfValue;
  std::uint8_t hb_sub = 1;
  for (const auto& s : rig.slaves) {
    v.push_back(dcfValue(canopen::kObjAssignment, s.id, s.boot.assignment, 4));
    const std::optional<std::uint32_t>* identity[] = {&s.boot.device_type, &s.boot.vendor_id, &s.boot.product_code,
                                                      &s.boot.revision, &s.boot.serial};
    for (std::uint16_t k = 0; k < 5; ++k)
      v.push_back(dcfValue(static_cast<std::uint16_t>(canopen::kObjDeviceType + k), s.id, identity[k]->value_or(0), 4));
    v.push_back(canopen::DcfEntry{canopen::kObjConciseDcf, s.id, canopen::encodeConciseDcf(s.boot.writes)});
    const std::uint32_t hb = (static_cast<std::uint32_t>(s.id) << 16) | consumerHeartbeatMs(s.heartbeat_ms);
    v.push_back(dcfValue(0x1016, hb_sub++, hb, 4));
  }
}

// One of the controller's PDOs: on cob (bit 31: off), mapped to its channels' objects in order.
void controllerPdo(canopen::ConciseDcf& v, bool transmit, unsigned n, std::uint32_t cob,
                   const std::vector<std::uint32_t>& map) {
  using canopen::dcfValue;
  const auto comm = static_cast<std::uint16_t>((transmit ? 0x1800 : 0x1400) + n - 1);
  const auto mapping = static_cast<std::uint16_t>((transmit ? 0x1A00 : 0x1600) + n - 1);
  v.push_back(dcfValue(comm, 1, cob, 4));
  if (map.empty()) return;
  v.push_back(dcfValue(mapping, 0, 0, 1));
  for (std::size_t i = 0; i < map.size(); ++i)
    v.push_back(dcfValue(mapping, static_cast<std::uint8_t>(i + 1), map[i], 4));
  v.push_back(dcfValue(mapping, 0, map.size(), 1));
}

std::uint32_t ownEntry(std::uint16_t index, unsigned bits) { return static_cast<std::uint32_t>(index) << 16 | bits; }

}  // namespace

canopen::ConciseDcf masterValues(const RigFile& rig) {
  using canopen::dcfValue;
  canopen::ConciseDcf v;
  v.push_back(dcfValue(canopen::kObjStartup, 0, rig.startup, 4));
  v.push_back(dcfValue(canopen::kObjBootTime, 0, rig.boot_time_ms, 4));
  slaveValues(rig, v);
  // The controller's own PDOs on the slaves' COB-IDs, mapped to the channels' objects.
  std::vector<std::uint32_t> rcob(rig.controller_rpdos + 1, 0), tcob(rig.controller_tpdos + 1, 0);
  std::vector<std::vector<std::uint32_t>> rmap(rcob.size()), tmap(tcob.size());
  for (std::size_t c = 0; c < rig.channels.size(); ++c) {
    const ChannelConfig& cc = rig.channels[c].cfg;
    rcob[cc.position_rpdo] = cc.layout.sensor_cob;
    if (cc.position_object == 0) rmap[cc.position_rpdo].push_back(ownEntry(positionObject(c), 32));
    tcob[cc.command_tpdo] = cc.layout.valve_cob;
    tmap[cc.command_tpdo].push_back(ownEntry(commandObject(c), 16));
    if (cc.layout.feedback) {
      rcob[cc.feedback_rpdo] = cc.layout.feedback_cob;
      rmap[cc.feedback_rpdo].push_back(ownEntry(pressureObject(c), 16));
    }
  }
  // The rest off: the EDS's predefined RPDO2 would otherwise listen on the valve's default COB-ID.
  for (unsigned n = 1; n < rcob.size(); ++n) controllerPdo(v, false, n, rcob[n] ? rcob[n] : 0x80000000u, rmap[n]);
  for (unsigned n = 1; n < tcob.size(); ++n) controllerPdo(v, true, n, tcob[n] ? tcob[n] : 0x80000000u, tmap[n]);
  return v;
}

}  // namespace pamc::nodes
