#include "nodes/emulator_node.hpp"

#include <algorithm>

namespace pamc::nodes {

using canopen::Frame;
using canopen::TimeUs;

EmulatorNodes::EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport)
    : cfg_(cfg), sensor_(cfg_, transport, inj_), valve_(cfg_, transport, inj_), plant_(cfg.plant) {
  scalingFromDevices();
  sync_cob_ = sensor_.node().od().ref<std::uint32_t>(0x1005, 0).get() & 0x7FFu;
  // The valve holds its command at 0 V (vented) until the controller sends one.
  plant_.reset(pd::kCommandMin, 0.0);  // vented: 0 V at the valve
  sensor_.measured(0, 0.0, cfg_.scaling.positionCounts(plant_.position()));
}

void EmulatorConfig::useProfileDevices(const std::string& od_dir) {
  sensor_eds = od_dir + "/profile/encoder406.eds";
  valve_eds = od_dir + "/profile/analog401.eds";
  sensor_id = valve_id = 0;  // theirs: 16 and 32
  position_index = 0x6004, position_sub = 0;
  command_index = 0x6411, command_sub = 2;    // the valve on output 2
  pressure_index = 0x6401, pressure_sub = 2;  // the pressure sensor on input 2
  scaling = pd::Scaling{};  // what the devices' dictionaries say replaces it (scalingFromDevices)
}

EmulatorConfig EmulatorConfig::profileDevices(const std::string& od_dir) {
  EmulatorConfig e;
  e.useProfileDevices(od_dir);
  return e;
}

// How the devices count, from their own dictionaries: the sensor's measuring step (CiA 406 0x6005:01,
// nm), the valve's and the pressure input's full scale (the HighLimit of their EDS entries; 16-bit
// full scale without one).
void EmulatorNodes::scalingFromDevices() {
  auto& sensor = sensor_.node().od();
  auto& valve = valve_.node().od();
  if (const auto* step = sensor.find(0x6005, 1)) cfg_.scaling.position_step_mm = step->asDouble() * 1e-6;
  std::int64_t full = 0;
  if (const auto* c = valve.find(cfg_.command_index, cfg_.command_sub); c && c->highLimit(full) && full > 0)
    cfg_.scaling.command_full_counts = static_cast<double>(full);
  if (const auto* p = valve.find(cfg_.pressure_index, cfg_.pressure_sub); p && p->highLimit(full) && full > 0)
    cfg_.scaling.pressure_full_counts = static_cast<double>(full);
}

void EmulatorNodes::start(TimeUs now) {
  sensor_.start(now);
  valve_.node().start(now);
}

// Physics over the cycle that just ended, under the command held during it.
void EmulatorNodes::onSync() {
  const std::uint64_t k = ++syncs_;
  const double t = time();
  const double F = cfg_.payload_at_s >= 0 && t >= cfg_.payload_at_s ? cfg_.payload_N : 0.0;
  plant_.step(valve_.held(), F);
  sensor_.measured(k, t, cfg_.scaling.positionCounts(plant_.measure()));
  valve_.reportPressure(plant_.pressure_bar());
}

void EmulatorNodes::onFrame(const Frame& f, TimeUs now) {
  sensor_.tick(now);
  const bool sync = (f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended();
  if (sync) onSync();
  sensor_.onFrame(f, now);
  valve_.node().onFrame(f, now);
  // The valve latched the command of the last cycle at this SYNC: it holds until the next one.
  if (sync) valve_.update(now);
}

void EmulatorNodes::advance(TimeUs now) {
  sensor_.tick(now);
  sensor_.advance(now);
  valve_.node().advance(now);
}

TimeUs EmulatorNodes::nextDeadline() const {
  return std::min(sensor_.nextDeadline(), valve_.node().nextDeadline());
}

}  // namespace pamc::nodes
