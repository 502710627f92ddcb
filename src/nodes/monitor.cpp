#include "nodes/monitor.hpp"

#include "canopen/frame_bits.hpp"

#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

namespace pamc::nodes {

static const char* stateName(int s) {
  switch (s) {
    case 0: return "boot-up";
    case 4: return "stopped";
    case 5: return "operational";
    case 127: return "pre-operational";
    case -1: return "(no heartbeat yet)";
  }
  return "?";
}

void Monitor::feed(const canopen::Frame& f, double t) {
  ++total_;
  frames_.emplace_back(t, static_cast<double>(canopen::frameBits(f)));  // with its stuff bits
  while (!frames_.empty() && frames_.front().first < t - 10.0) frames_.pop_front();
  const std::uint32_t id = f.id & 0x7FFu;
  if (f.extended()) {
    ++unknown_;
    return;
  }
  if (id == dict_.sync_cob) {
    syncs_.push_back(t);
    while (!syncs_.empty() && syncs_.front() < t - 10.0) syncs_.pop_front();
    return;
  }
  if (id >= 0x701 && id <= 0x77F && f.len == 1) {
    auto& n = nodes_[static_cast<std::uint8_t>(id - 0x700)];
    n.state = f.data[0] & 0x7F;
    n.last_hb = t;
    return;
  }
  if (id >= 0x081 && id <= 0x0FF && f.len == 8) {
    ++emcy_count_;
    const unsigned code = f.data[0] | (f.data[1] << 8);
    char b[160];
    const auto it = dict_.nodes.find(static_cast<std::uint8_t>(id - 0x80));
    std::snprintf(b, sizeof b, "%10.3f s  node %u (%s): EMCY 0x%04X, error register 0x%02X%s", t, id - 0x80,
                  it == dict_.nodes.end() ? "?" : it->second.c_str(), code, f.data[2],
                  code == 0 ? " (error reset)" : "");
    emcy_log_.push_back(b);
    if (emcy_log_.size() > 8) emcy_log_.pop_front();
    return;
  }
  if (id == 0x000 || (id >= 0x581 && id <= 0x67F)) return;  // NMT, SDO
  const auto it = dict_.pdos.find(id);
  if (it == dict_.pdos.end()) {
    ++unknown_;
    return;
  }
  std::vector<double> v;
  if (!decodePdo(it->second, f, v)) {
    ++bad_length_;
    return;
  }
  for (size_t i = 0; i < v.size(); ++i) {
    const auto& fl = it->second.fields[i];
    values_[fl.column + (fl.role.empty() ? "" : " (" + fl.role + ")")] = {v[i], fl.unit};
  }
}

std::string Monitor::render(double t, double window) const {
  std::ostringstream o;
  char b[200];
  double bits = 0;
  for (const auto& [ft, fb] : frames_)
    if (ft >= t - window) bits += fb;
  std::vector<double> dts;
  for (size_t i = 1; i < syncs_.size(); ++i)
    if (syncs_[i] >= t - window) dts.push_back(syncs_[i] - syncs_[i - 1]);
  double mean = 0, jit = 0;
  for (double d : dts) mean += d;
  if (!dts.empty()) mean /= static_cast<double>(dts.size());
  for (double d : dts) jit = std::max(jit, std::fabs(d - mean));
  std::snprintf(b, sizeof b, "pamc monitor   t = %.3f s   frames %llu   bus load %.1f %% of %.0f kbit/s\n", t,
                static_cast<unsigned long long>(total_), 100.0 * bits / window / bitrate_, bitrate_ / 1e3);
  o << b;
  std::snprintf(b, sizeof b, "SYNC 0x%03X: %.1f Hz (period %.3f ms, max jitter %.1f us)\n", dict_.sync_cob,
                dts.empty() ? 0.0 : 1.0 / mean, mean * 1e3, jit * 1e6);
  o << b << "\nNodes\n";
  std::map<std::uint8_t, std::string> names = dict_.nodes;
  for (const auto& [id, n] : nodes_) names.emplace(id, "?");
  for (const auto& [id, name] : names) {
    const auto it = nodes_.find(id);
    const int st = it == nodes_.end() ? -1 : it->second.state;
    const double age = it == nodes_.end() ? -1 : t - it->second.last_hb;
    std::snprintf(b, sizeof b, "  %3u %-12s %-18s %s\n", id, name.c_str(), stateName(st),
                  age < 0 ? "" : (age > 1.0 ? "heartbeat LOST" : ""));
    o << b;
  }
  o << "\nProcess data (latest)\n";
  for (const auto& [k, v] : values_) {
    std::snprintf(b, sizeof b, "  %-40s %14.4f %s\n", k.c_str(), v.first, v.second.c_str());
    o << b;
  }
  o << "\nEmergencies (" << emcy_count_ << ")\n";
  for (const auto& e : emcy_log_) o << "  " << e << "\n";
  std::snprintf(b, sizeof b, "\nunknown COB-IDs %llu, wrong lengths %llu\n", static_cast<unsigned long long>(unknown_),
                static_cast<unsigned long long>(bad_length_));
  o << b;
  return o.str();
}

}  // namespace pamc::nodes
