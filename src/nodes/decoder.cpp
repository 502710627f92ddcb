#include "nodes/decoder.hpp"

#include "nodes/process_data.hpp"

#include <dirent.h>
#include <sys/stat.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "canopen/eds_dictionary.hpp"
#include "canopen/pdo.hpp"
#include "nodes/rig_file.hpp"

namespace pamc::nodes {

namespace {

std::string stem(const std::string& path) {
  std::string s = path.substr(path.find_last_of('/') + 1);
  const auto dot = s.rfind('.');
  return dot == std::string::npos ? s : s.substr(0, dot);
}

std::string sanitize(const std::string& s) {
  std::string o;
  for (char c : s) {
    if (std::isalnum(static_cast<unsigned char>(c)))
      o += static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    else if (!o.empty() && o.back() != '_')
      o += '_';
  }
  while (!o.empty() && o.back() == '_') o.pop_back();
  return o;
}

std::vector<std::string> expand(const std::vector<std::string>& paths) {
  std::vector<std::string> files;
  for (const auto& p : paths) {
    struct stat st {};
    if (::stat(p.c_str(), &st) != 0)
      throw std::runtime_error(p + ": no such file or directory (give --od with the EDS files or their directory)");
    if (S_ISDIR(st.st_mode)) {
      DIR* d = ::opendir(p.c_str());
      if (!d) throw std::runtime_error(p + ": cannot read directory");
      std::vector<std::string> found;
      while (auto* e = ::readdir(d)) {
        const std::string n = e->d_name;
        if (n.size() > 4 && n.compare(n.size() - 4, 4, ".eds") == 0) found.push_back(p + "/" + n);
      }
      ::closedir(d);
      std::sort(found.begin(), found.end());
      if (found.empty()) throw std::runtime_error(p + ": no .eds files in this directory");
      files.insert(files.end(), found.begin(), found.end());
    } else {
      files.push_back(p);
    }
  }
  return files;
}

// Known process data of the rig, in engineering units.
void roleOf(PdoField& f) {
  if (f.index == 0x6004 && f.sub == 0) {
    f.role = "y", f.scale = pd::kPositionStep_mm, f.unit = "mm";  // CiA 406 position, 0.001 mm steps
  } else if (f.index == 0x6411 && f.sub == 1) {
    f.role = "u", f.scale = pd::kValveFullScale_V / pd::kAnalogFullScaleCounts, f.offset = -pd::kValveMid_V,
    f.unit = "V";  // command relative to mid-range
  } else if (f.index == 0x6401 && f.sub == 1) {
    f.role = "p", f.scale = pd::kPressureFullScale_bar / pd::kAnalogFullScaleCounts, f.unit = "bar";
  }
}

}  // namespace

BusDictionary loadBusDictionary(const std::vector<std::string>& paths) {
  BusDictionary bd;
  for (const auto& file : expand(paths)) {
    const auto eds = canopen::EdsFile::load(file);
    const std::uint8_t id = eds.node_id;
    if (id == 0)
      throw std::runtime_error(file + ": no NodeID in [DeviceComissioning]; the COB-IDs ($NODEID) cannot be resolved");
    auto od = canopen::dictionaryFromEds(eds, id);
    const std::string dev = stem(file);
    bd.nodes[id] = dev;
    // Communication parameters are read as the node reads them (any integer type, absent = unused), and
    // a mapping the decoder cannot use is an error naming the file and the mapping entry.
    auto fail = [&](const std::string& what) { throw std::runtime_error(file + ": " + what); };
    if (const auto* sync = od.find(0x1005, 0)) {
      const auto cob = static_cast<std::uint32_t>(sync->asUnsigned());
      if (cob & 0x40000000u) {
        bd.sync_cob = cob & 0x7FFu;
        if (const auto* period = od.find(0x1006, 0))
          bd.sync_period_s = static_cast<double>(period->asUnsigned()) * 1e-6;
      }
    }
    // TPDOs the node sends, and RPDOs it receives (whose sender may have no EDS here).
    for (int dir = 0; dir < 2; ++dir) {
      const std::uint16_t comm0 = dir == 0 ? 0x1800 : 0x1400, map0 = dir == 0 ? 0x1A00 : 0x1600;
      for (std::uint16_t n = 0; n < 512; ++n) {
        const auto map = static_cast<std::uint16_t>(map0 + n);
        canopen::PdoMapping mapping;
        const std::uint32_t read = canopen::readPdoMapping(od, map, mapping);
        if (read == canopen::kAbortNoObject) continue;  // no mapping: no PDO
        const std::uint32_t cob = canopen::readPdoCobId(od, static_cast<std::uint16_t>(comm0 + n));
        if (cob & canopen::kPdoInvalidBit) continue;  // not valid, or no COB-ID
        PdoLayout l;
        l.cob_id = cob & canopen::kStandardIdMask;
        l.device = dev;
        l.node_id = id;
        if (read == canopen::kAbortValueRange)
          fail(canopen::entryName(map, 0) + " maps " + std::to_string(mapping.count) + " objects; a PDO has at most 8");
        unsigned total = 0;
        for (std::uint8_t i = 0; i < mapping.read; ++i) {
          const canopen::PdoMappingEntry m = mapping.entries[i];
          const auto s = static_cast<std::uint8_t>(i + 1);
          PdoField f;
          f.index = m.index();
          f.sub = m.sub();
          const std::string what = canopen::entryName(map, s) + " maps " + canopen::entryName(f.index, f.sub) +
                                   " with " + std::to_string(m.bits()) + " bits";
          if (m.bits() == 0 || m.bits() % 8 != 0) fail(what + "; only whole bytes are decoded");
          f.bytes = static_cast<std::uint8_t>(m.bits() / 8);
          if (od.hasObject(f.index)) {
            const auto* e = od.find(f.index, f.sub);
            if (e == nullptr) fail(what + ", but the dictionary has no such entry");
            if (canopen::dataTypeSize(e->dataType()) != f.bytes) {
              fail(what + ", but it is " + canopen::dataTypeName(e->dataType()));
            }
            f.type = e->dataType();
            f.column = dev + "." + sanitize(e->name());
          } else {
            f.column = dev + "." + std::to_string(f.index) + "_" + std::to_string(f.sub);  // dummy mapping
          }
          roleOf(f);
          l.fields.push_back(f);
          total += f.bytes;
          if (total > 8) fail(canopen::entryName(map, 0) + " maps more than the 8 bytes of a CAN frame");
          l.length = static_cast<std::uint8_t>(total);
        }
        if (read == canopen::kAbortNoSubIndex)
          fail(canopen::entryName(map, static_cast<std::uint8_t>(mapping.read + 1)) + " is missing; " +
               canopen::entryName(map, 0) + " says " + std::to_string(mapping.count) + " objects are mapped");
        // A COB-ID described twice (sender's TPDO and receiver's RPDO): keep the one with roles.
        auto it = bd.pdos.find(l.cob_id);
        const bool has_role =
            std::any_of(l.fields.begin(), l.fields.end(), [](const PdoField& f) { return !f.role.empty(); });
        if (it == bd.pdos.end() || has_role) bd.pdos[l.cob_id] = l;
      }
    }
  }
  return bd;
}

namespace {
// A field of a PDO on cob, from node id of device dev, in role with its scaling; the fields of one
// PDO in the order they are added (the channels' order, their order in the PDO).
void addField(BusDictionary& bd, std::uint32_t cob, const std::string& dev, std::uint8_t id, const RigObject& o,
              const std::string& name, const std::string& role, double scale, double offset, const char* unit) {
  PdoField f;
  f.index = o.index;
  f.sub = o.sub;
  f.type = o.type;
  f.bytes = static_cast<std::uint8_t>(canopen::dataTypeSize(o.type));
  f.column = dev + "." + name;
  f.role = role;
  f.scale = scale;
  f.offset = offset;
  f.unit = unit;
  PdoLayout& l = bd.pdos[cob];
  l.cob_id = cob;
  l.device = dev;
  l.node_id = id;
  l.fields.push_back(f);
  l.length = static_cast<std::uint8_t>(l.length + f.bytes);
}
}  // namespace

// Channel c's column of a role: "y" for channel 1, "y2" for channel 2, ...
std::string channelRole(const char* role, std::size_t c) {
  return c == 0 ? std::string(role) : role + std::to_string(c + 1);
}

BusDictionary busDictionaryFromRig(const RigFile& rig) {
  BusDictionary bd;
  bd.sync_period_s = static_cast<double>(rig.period_us) * 1e-6;
  bd.nodes[rig.controller_id] = "controller";
  for (const auto& s : rig.slaves) bd.nodes[s.id] = s.name;
  for (std::size_t c = 0; c < rig.channels.size(); ++c) {
    const RigChannel& ch = rig.channels[c];
    const ChannelConfig& cc = ch.cfg;
    const pd::Scaling& s = cc.layout.scaling;
    const std::string sensor = rig.slave(cc.sensor_id).name, valve = rig.slave(cc.valve_id).name;
    const std::string n = rig.channels.size() > 1 ? std::to_string(c + 1) : std::string();
    addField(bd, cc.layout.sensor_cob, sensor, cc.sensor_id, ch.position, "position" + n, channelRole("y", c),
             s.position_step_mm, 0.0, "mm");
    // Counts -> volts over 0..10 V, relative to mid-range as the controller's u.
    const double v_per_count = pd::kValveFullScale_V / s.command_full_counts;
    addField(bd, cc.layout.valve_cob, valve, cc.valve_id, ch.command, "command" + n, channelRole("u", c), v_per_count,
             -s.command_zero_counts * v_per_count - pd::kValveMid_V, "V");
    if (cc.layout.feedback)
      addField(bd, cc.layout.feedback_cob, valve, cc.valve_id, ch.feedback, "pressure" + n, channelRole("p", c),
               pd::kPressureFullScale_bar / s.pressure_full_counts, 0.0, "bar");
  }
  return bd;
}

bool decodePdo(const PdoLayout& l, const canopen::Frame& fr, std::vector<double>& out) {
  if (fr.len < l.length) return false;
  out.clear();
  size_t off = 0;
  for (const auto& f : l.fields) {
    std::uint64_t raw = 0;
    for (size_t b = 0; b < f.bytes && off + b < 8; ++b) raw |= static_cast<std::uint64_t>(fr.data[off + b]) << (8 * b);
    double v;
    using canopen::DataType;
    switch (f.type) {
      case DataType::Integer8: v = static_cast<std::int8_t>(raw); break;
      case DataType::Integer16: v = static_cast<std::int16_t>(raw); break;
      case DataType::Integer32: v = static_cast<std::int32_t>(raw); break;
      case DataType::Integer64: v = static_cast<double>(static_cast<std::int64_t>(raw)); break;
      case DataType::Real32: {
        float x;
        std::uint32_t r32 = static_cast<std::uint32_t>(raw);
        std::memcpy(&x, &r32, 4);
        v = x;
        break;
      }
      case DataType::Real64: {
        double x;
        std::memcpy(&x, &raw, 8);
        v = x;
        break;
      }
      default: v = static_cast<double>(raw); break;
    }
    out.push_back(v * f.scale + f.offset);
    off += f.bytes;
  }
  return true;
}

DecodedRun decodeCandump(const std::vector<canopen::CandumpRecord>& log, const BusDictionary& dict) {
  DecodedRun run;
  // Columns: the roles first, then every other field.
  std::map<std::string, size_t> col;
  run.columns = {"t", "u", "y", "p", "t_log"};
  // Channels 2.. of a rig with several: u2, y2, p2, ... after t_log.
  std::size_t channels = 1;
  for (const auto& [cob, l] : dict.pdos)
    for (const auto& f : l.fields)
      if (f.role.size() > 1 && (f.role[0] == 'u' || f.role[0] == 'y' || f.role[0] == 'p'))
        channels = std::max<std::size_t>(channels, std::stoul(f.role.substr(1)));
  for (std::size_t c = 1; c < channels; ++c)
    for (const char* r : {"u", "y", "p"}) run.columns.push_back(channelRole(r, c));
  for (size_t i = 0; i < run.columns.size(); ++i) col[run.columns[i]] = i;
  for (const auto& [cob, l] : dict.pdos)
    for (const auto& f : l.fields)
      if (f.role.empty() && !col.count(f.column)) {
        col[f.column] = run.columns.size();
        run.columns.push_back(f.column);
      }
  std::vector<double> cur(run.columns.size(), NAN);
  std::vector<double> last(run.columns.size(), NAN);  // last value seen of every column
  std::vector<double> vals;
  // Per channel: the last command sent, the one latched at the last SYNC and at the one before.
  std::vector<double> latest_u(channels, NAN), latched_prev(channels, NAN), latched_now(channels, NAN);
  std::vector<std::size_t> iu(channels);
  for (std::size_t c = 0; c < channels; ++c) iu[c] = col[channelRole("u", c)];
  double t0 = NAN;
  std::int64_t k = -1, k_first = -1;
  const size_t iy = col["y"];
  auto emit = [&](double sync_time) {
    // Row for the cycle that started at the previous SYNC. A value that did not arrive in this
    // cycle (a lost PDO) holds its last one, so the time base stays even; such cycles are counted.
    if (k < 1 || std::isnan(latched_prev[0])) return;
    if (std::isnan(cur[iy]) && std::isnan(last[iy])) return;  // no position yet
    if (std::isnan(cur[iy])) ++run.held;
    std::vector<double> row(cur.size());
    for (size_t i = 0; i < cur.size(); ++i) {
      if (!std::isnan(cur[i])) last[i] = cur[i];
      row[i] = last[i];
    }
    for (std::size_t c = 0; c < channels; ++c) row[iu[c]] = latched_prev[c];
    row[col["t_log"]] = sync_time;
    row[0] = static_cast<double>(k - 1);  // SYNC index of the cycle; scaled to seconds below
    if (k_first < 0) k_first = k - 1;
    run.rows.push_back(row);
  };
  double last_sync_t = 0;
  for (const auto& rec : log) {
    const auto& f = rec.frame;
    ++run.frames;
    const double ts = rec.unix_time_us * 1e-6;
    if (std::isnan(t0)) t0 = ts;
    if (f.id == dict.sync_cob && !f.extended() && !f.error() && !f.remote()) {
      emit(last_sync_t);
      ++k;
      ++run.syncs;
      last_sync_t = ts - t0;
      // The valve latches the last command it received; it holds over the cycle starting now.
      latched_prev = latched_now;
      latched_now = latest_u;
      cur.assign(cur.size(), NAN);
      continue;
    }
    auto it = dict.pdos.find(f.id);
    if (it == dict.pdos.end() || f.extended()) {
      // NMT, EMCY, SDO and heartbeats are expected traffic, just not process data.
      const bool service = !f.extended() && (f.id == 0x000 || (f.id >= 0x081 && f.id <= 0x0FF) ||
                                             (f.id >= 0x581 && f.id <= 0x67F) || (f.id >= 0x701 && f.id <= 0x77F));
      if (!service) ++run.unknown;
      continue;
    }
    if (!decodePdo(it->second, f, vals)) {
      ++run.bad_length;
      continue;
    }
    for (size_t i = 0; i < vals.size(); ++i) {
      const auto& fl = it->second.fields[i];
      if (!fl.role.empty() && fl.role[0] == 'u')
        latest_u[fl.role.size() > 1 ? std::stoul(fl.role.substr(1)) - 1 : 0] = vals[i];
      else if (!fl.role.empty())
        cur[col[fl.role]] = vals[i];
      else
        cur[col[fl.column]] = vals[i];
    }
  }
  // A node whose first PDO came a cycle or more after the first position (the valve answering late
  // after its start) leaves its column empty in the first rows, and a measurement has no empty cells:
  // the decoded run starts at the first row in which every column that ever has a value has one.
  // (Values hold from then on, so only leading rows can have gaps.)
  {
    std::vector<bool> ever(run.columns.size(), false);
    for (const auto& r : run.rows)
      for (size_t c = 0; c < r.size(); ++c) ever[c] = ever[c] || !std::isnan(r[c]);
    size_t first = 0;
    while (first < run.rows.size()) {
      bool complete = true;
      for (size_t c = 0; c < ever.size(); ++c) complete = complete && (!ever[c] || !std::isnan(run.rows[first][c]));
      if (complete) break;
      ++first;
    }
    run.rows.erase(run.rows.begin(), run.rows.begin() + static_cast<std::ptrdiff_t>(first));
    if (!run.rows.empty()) k_first = static_cast<std::int64_t>(run.rows.front()[0]);
  }
  // Even time base: SYNC index times the SYNC period (from the EDS, or measured from the log when the
  // two disagree); t_log keeps the log's own stamps.
  double period = dict.sync_period_s;
  if (run.rows.size() > 2) {
    const double span = run.rows.back()[col["t_log"]] - run.rows.front()[col["t_log"]];
    const double cycles = run.rows.back()[0] - run.rows.front()[0];
    const double measured = cycles > 0 ? span / cycles : period;
    if (measured > 0 && std::fabs(measured - period) > 0.2 * period) period = measured;
  }
  for (auto& r : run.rows) r[0] = (r[0] - static_cast<double>(k_first)) * period;
  // Columns that never had a value are left out.
  std::vector<size_t> keep;
  for (size_t c = 0; c < run.columns.size(); ++c) {
    bool any = false;
    for (const auto& r : run.rows) any = any || !std::isnan(r[c]);
    if (any || c < 3) keep.push_back(c);
  }
  if (keep.size() < run.columns.size()) {
    std::vector<std::string> cols;
    for (size_t c : keep) cols.push_back(run.columns[c]);
    for (auto& r : run.rows) {
      std::vector<double> nr;
      for (size_t c : keep) nr.push_back(r[c]);
      r.swap(nr);
    }
    run.columns = cols;
  }
  return run;
}

}  // namespace pamc::nodes
