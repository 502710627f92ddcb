#include "nodes/rig_file.hpp"

#include <sys/stat.h>

#include <algorithm>
#include <cstdio>
#include <set>
#include <vector>

#include "canopen/eds_dictionary.hpp"
#include "canopen/ini.hpp"
#include "canopen/od.hpp"

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
const std::set<std::string> kControllerKeys = {"node_id", "eds", "startup", "boot_time_ms"};
const std::set<std::string> kSlaveCommon = {"node_id",  "eds",    "device_type", "vendor_id",    "product_code",
                                            "revision", "serial", "heartbeat_ms", "master_heartbeat_ms",
                                            "boot",     "mandatory", "keep_alive", "retries"};
const std::set<std::string> kSensorKeys = {"position", "position_step_mm", "tpdo", "cob_id"};
const std::set<std::string> kValveKeys = {"command", "command_full_counts", "command_zero_counts", "rpdo", "cob_id",
                                          "feedback", "feedback_full_counts", "feedback_tpdo", "feedback_cob_id"};

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
        fail(k.line, "reset: 0x1F81 bit 4 is keep alive (CiA 302-2); a slave back after a heartbeat loss is reset "
                     "unless keep_alive = yes");
      if (a.count(n) == 0 && b.count(n) == 0) fail(k.line, "unknown key '" + k.name + "' in [" + s.name + "]");
    }
  }
  std::uint64_t unsignedKey(const IniSection& s, const char* key, std::uint64_t def, std::uint64_t lo,
                            std::uint64_t hi) const {
    const IniKey* k = s.find(key);
    if (k == nullptr) return def;
    std::uint64_t v = 0;
    if (!canopen::parseIniUnsigned(k->value, v)) fail(k->line, std::string(key) + " '" + k->value + "' is not a number");
    if (v < lo || v > hi)
      fail(k->line, std::string(key) + " " + k->value + " is outside " + std::to_string(lo) + ".." + std::to_string(hi));
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

// A PDO of the slave set up for the cycle: disabled, synchronous, mapped to `mapped`, enabled on cob.
void pdoWrites(const Reader& r, SlaveBuild& s, int line, bool transmit, unsigned n, std::uint32_t cob,
               const canopen::Entry& mapped) {
  const std::uint16_t comm = static_cast<std::uint16_t>((transmit ? 0x1800 : 0x1400) + n - 1);
  const std::uint16_t map = static_cast<std::uint16_t>((transmit ? 0x1A00 : 0x1600) + n - 1);
  const char* what = transmit ? "TPDO" : "RPDO";
  if (s.od.find(comm, 1) == nullptr || s.od.find(comm, 2) == nullptr || s.od.find(map, 0) == nullptr ||
      s.od.find(map, 1) == nullptr)
    r.fail(line, s.eds + " has no " + what + " " + std::to_string(n) + " (" + hex(comm, 4) + " / " + hex(map, 4) + ")");
  if (!mapped.pdoMappable())
    r.fail(line, s.eds + ": " + objName(mapped.index(), mapped.subIndex()) + " cannot be mapped into a PDO");
  const std::uint32_t entry_value = (static_cast<std::uint32_t>(mapped.index()) << 16) |
                                    (static_cast<std::uint32_t>(mapped.subIndex()) << 8) |
                                    static_cast<std::uint32_t>(mapped.size() * 8);
  auto& w = s.boot.writes;
  w.push_back(dcfValue(comm, 1, cob | 0x80000000u, 4));  // CiA 301: change a PDO only while it is disabled
  w.push_back(dcfValue(comm, 2, 1, 1));                  // synchronous, every SYNC
  if (const auto* et = s.od.find(comm, 5); et != nullptr && et->writable()) w.push_back(dcfValue(comm, 5, 0, 2));
  w.push_back(dcfValue(map, 0, 0, 1));
  w.push_back(dcfValue(map, 1, entry_value, 4));
  w.push_back(dcfValue(map, 0, 1, 1));
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
  SlaveBuild s{&sec, 0, {}, ObjectDictionary({}, {}), {}, 0};
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
RigFile fromIni(const canopen::IniFile& ini) {
  const std::string& path = ini.path;
  const Reader r(ini);
  for (const auto& s : ini.sections) {
    static const std::set<std::string> known = {"bus", "controller", "sensor", "valve", "sensor.sdo", "valve.sdo"};
    std::string n = s.name;
    std::transform(n.begin(), n.end(), n.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
    if (known.count(n) == 0) r.fail(s.line, "unknown section [" + s.name + "] (known: bus, controller, sensor, valve, sensor.sdo, valve.sdo)");
  }
  RigFile rig;
  rig.path = path;
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

  // The sensor: its position TPDO.
  const IniSection& ss = r.need("sensor");
  r.knownKeys(ss, kSlaveCommon, kSensorKeys);
  SlaveBuild sensor = slaveCommon(r, ss, rig.controller_id);
  const IniKey& pos_key = r.needKey(ss, "position");
  const auto [pidx, psub] = r.object(pos_key);
  const canopen::Entry& pos = entry(r, sensor, pos_key.line, pidx, psub);
  if (pos.size() != 4 || !(pos.dataType() == canopen::DataType::Integer32 || pos.dataType() == canopen::DataType::Unsigned32))
    r.fail(pos_key.line, sensor.eds + ": " + objName(pidx, psub) + " is not 32 bits: the controller takes 32-bit positions");
  const unsigned tpdo = static_cast<unsigned>(r.unsignedKey(ss, "tpdo", 1, 1, 512));
  const int tpdo_line = ss.find("tpdo") ? ss.find("tpdo")->line : pos_key.line;
  rig.layout.sensor_cob = static_cast<std::uint32_t>(
      r.unsignedKey(ss, "cob_id", defaultPdoCob(r, tpdo_line, true, tpdo, sensor.id), 1, 0x7FF));
  otherTpdosOff(sensor, tpdo);
  pdoWrites(r, sensor, tpdo_line, true, tpdo, rig.layout.sensor_cob, pos);
  if (const IniKey* k = ss.find("position_step_mm")) {
    if (k->value == "device") {
      // Read at boot; until then (and for decoding a log) the EDS's default, if it has one.
      const canopen::Entry& step = entry(r, sensor, k->line, 0x6005, 1);
      if (step.asUnsigned() > 0) rig.layout.scaling.position_step_mm = static_cast<double>(step.asUnsigned()) * 1e-6;
      rig.layout.position_step_from_device = true;
    } else {
      rig.layout.scaling.position_step_mm = r.doubleKey(ss, "position_step_mm", 0, 1e-9, 1e3);
      if (!(rig.layout.scaling.position_step_mm > 0)) r.fail(k->line, "position_step_mm must be above 0");
    }
  }
  slaveTail(r, ini, sensor, rig.controller_id);

  // The valve: its command RPDO, its feedback TPDO, its error value.
  const IniSection& vs = r.need("valve");
  r.knownKeys(vs, kSlaveCommon, kValveKeys);
  SlaveBuild valve = slaveCommon(r, vs, rig.controller_id);
  const IniKey& cmd_key = r.needKey(vs, "command");
  const auto [cidx, csub] = r.object(cmd_key);
  const canopen::Entry& cmd = entry(r, valve, cmd_key.line, cidx, csub);
  if (cmd.size() != 2 || !cmd.writable())
    r.fail(cmd_key.line, valve.eds + ": " + objName(cidx, csub) + " is not a writable 16-bit object: the controller sends 16-bit commands");
  const unsigned rpdo = static_cast<unsigned>(r.unsignedKey(vs, "rpdo", 1, 1, 512));
  const int rpdo_line = vs.find("rpdo") ? vs.find("rpdo")->line : cmd_key.line;
  rig.layout.valve_cob = static_cast<std::uint32_t>(
      r.unsignedKey(vs, "cob_id", defaultPdoCob(r, rpdo_line, false, rpdo, valve.id), 1, 0x7FF));
  pdoWrites(r, valve, rpdo_line, false, rpdo, rig.layout.valve_cob, cmd);
  rig.layout.scaling.command_full_counts = r.doubleKey(vs, "command_full_counts", rig.layout.scaling.command_full_counts, 1, 65535);
  rig.layout.scaling.command_zero_counts = r.doubleKey(vs, "command_zero_counts", 0.0, -32768, 32767);
  // CiA 401: output n has its error mode 0x6443:n and error value 0x6444:n.
  rig.layout.error_value_index = 0;
  if (cidx == 0x6411 && valve.od.find(0x6444, csub) != nullptr) {
    rig.layout.error_value_index = 0x6444;
    rig.layout.error_value_sub = csub;
    if (const auto* mode = valve.od.find(0x6443, csub); mode != nullptr && mode->writable())
      valve.boot.writes.push_back(dcfValue(0x6443, csub, 1, mode->size()));  // output the error value on a communication error
  }
  unsigned feedback_tpdo = 0;
  if (const IniKey* fb_key = vs.find("feedback")) {
    const auto [fidx, fsub] = r.object(*fb_key);
    const canopen::Entry& fb = entry(r, valve, fb_key->line, fidx, fsub);
    if (fb.size() != 2) r.fail(fb_key->line, valve.eds + ": " + objName(fidx, fsub) + " is not 16 bits: the controller takes 16-bit feedback");
    feedback_tpdo = static_cast<unsigned>(r.unsignedKey(vs, "feedback_tpdo", 1, 1, 512));
    const int line = vs.find("feedback_tpdo") ? vs.find("feedback_tpdo")->line : fb_key->line;
    rig.layout.feedback_cob = static_cast<std::uint32_t>(
        r.unsignedKey(vs, "feedback_cob_id", defaultPdoCob(r, line, true, feedback_tpdo, valve.id), 1, 0x7FF));
    otherTpdosOff(valve, feedback_tpdo);
    pdoWrites(r, valve, line, true, feedback_tpdo, rig.layout.feedback_cob, fb);
    rig.layout.scaling.pressure_full_counts = r.doubleKey(vs, "feedback_full_counts", rig.layout.scaling.pressure_full_counts, 1, 65535);
    rig.feedback = RigObject{fidx, fsub, fb.dataType()};
  } else {
    rig.layout.feedback = false;
    otherTpdosOff(valve, 0);
  }
  slaveTail(r, ini, valve, rig.controller_id);

  // One node per ID, one producer per COB-ID.
  if (sensor.id == valve.id || sensor.id == rig.controller_id || valve.id == rig.controller_id)
    r.fail(vs.find("node_id")->line, "node-IDs of controller, sensor and valve must differ");
  const std::uint32_t cobs[] = {rig.layout.sensor_cob, rig.layout.valve_cob, rig.layout.feedback_cob};
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j)
      if (cobs[i] != 0 && cobs[i] == cobs[j]) r.fail(0, "two PDOs on COB-ID " + hex(cobs[i], 3));

  rig.sensor_id = sensor.id;
  rig.valve_id = valve.id;
  rig.sensor_eds = sensor.eds;
  rig.valve_eds = valve.eds;
  if (rig.layout.position_step_from_device) sensor.boot.assignment |= canopen::kAssignBoot;  // the step is read at boot
  rig.sensor_boot = std::move(sensor.boot);
  rig.valve_boot = std::move(valve.boot);
  rig.sensor_heartbeat_ms = sensor.heartbeat_ms;
  rig.valve_heartbeat_ms = valve.heartbeat_ms;
  rig.position = RigObject{pidx, psub, pos.dataType()};
  rig.command = RigObject{cidx, csub, cmd.dataType()};
  return rig;
}
}  // namespace

void applyRig(const RigFile& rig, ControllerNodeConfig& cfg) {
  cfg.eds_path = rig.controller_eds;
  cfg.node_id = rig.controller_id;
  cfg.period_us = rig.period_us;
  cfg.sensor_id = rig.sensor_id;
  cfg.valve_id = rig.valve_id;
  cfg.layout = rig.layout;
  cfg.dictionary = masterValues(rig);
}

}  // namespace pamc::nodes

namespace pamc::nodes {

canopen::ConciseDcf masterValues(const RigFile& rig) {
  using canopen::dcfValue;
  canopen::ConciseDcf v;
  v.push_back(dcfValue(canopen::kObjStartup, 0, rig.startup, 4));
  v.push_back(dcfValue(canopen::kObjBootTime, 0, rig.boot_time_ms, 4));
  const struct {
    std::uint8_t id;
    const canopen::SlaveBoot& boot;
    unsigned heartbeat_ms;
  } slaves[] = {{rig.sensor_id, rig.sensor_boot, rig.sensor_heartbeat_ms}, {rig.valve_id, rig.valve_boot, rig.valve_heartbeat_ms}};
  std::uint8_t hb_sub = 1;  // 0x1016:01 the sensor's, :02 the valve's
  for (const auto& s : slaves) {
    v.push_back(dcfValue(canopen::kObjAssignment, s.id, s.boot.assignment, 4));
    const std::optional<std::uint32_t>* identity[] = {&s.boot.device_type, &s.boot.vendor_id, &s.boot.product_code,
                                                      &s.boot.revision, &s.boot.serial};
    for (std::uint16_t k = 0; k < 5; ++k)
      v.push_back(dcfValue(static_cast<std::uint16_t>(canopen::kObjDeviceType + k), s.id, identity[k]->value_or(0), 4));
    v.push_back(canopen::DcfEntry{canopen::kObjConciseDcf, s.id, canopen::encodeConciseDcf(s.boot.writes)});
    const std::uint32_t hb = (static_cast<std::uint32_t>(s.id) << 16) | consumerHeartbeatMs(s.heartbeat_ms);
    v.push_back(dcfValue(0x1016, hb_sub++, hb, 4));
  }
  // The controller's own PDOs on the slaves' COB-IDs: RPDO1 the position, RPDO2 the feedback, TPDO1 the command.
  const auto& lay = rig.layout;
  v.push_back(dcfValue(0x1400, 1, lay.sensor_cob, 4));
  v.push_back(dcfValue(0x1401, 1, lay.feedback ? lay.feedback_cob : 0x80000000u, 4));
  v.push_back(dcfValue(0x1800, 1, lay.valve_cob, 4));
  return v;
}

}  // namespace pamc::nodes
