#include "nodes/emulator_node.hpp"

#include <algorithm>
#include <stdexcept>

namespace pamc::nodes {

using canopen::Frame;
using canopen::TimeUs;

EmulatorNodes::EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport)
    : cfg_(cfg), clean_(cfg), valve_(cfg_, transport, inj_) {
  clean_.sensor_silent_at_s = -1, clean_.drop_pdo_prob = 0.0, clean_.late_pdo_cycles = 0;
  if (cfg_.fault_channel >= cfg_.channels()) throw std::invalid_argument("emulator: fault channel beyond the channels");
  plants_.reserve(cfg_.channels());
  for (std::size_t c = 0; c < cfg_.channels(); ++c) {
    const bool faulty = c == cfg_.fault_channel;
    const std::uint8_t id = cfg_.sensor_ids.empty() ? cfg_.sensor_id : cfg_.sensor_ids[c];
    sensors_.push_back(std::make_unique<EmulatedSensor>(faulty ? cfg_ : clean_, transport, faulty ? inj_ : none_, id));
    plant::PlantConfig pc = cfg.plant;
    pc.seed += c;  // each muscle its own noise
    pc.physics.seed += c;
    plants_.emplace_back(pc);
  }
  scalingFromDevices();
  sync_cob_ = sensors_[0]->node().od().ref<std::uint32_t>(0x1005, 0).get() & 0x7FFu;
  // The valve holds its command at 0 V (vented) until the controller sends one.
  for (std::size_t c = 0; c < plants_.size(); ++c) {
    plants_[c].reset(pd::kCommandMin, 0.0);  // vented: 0 V at the valve
    sensors_[c]->measured(0, 0.0, cfg_.scaling.positionCounts(plants_[c].position()));
  }
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
  auto& sensor = sensors_[0]->node().od();
  auto& valve = valve_.node().od();
  if (const auto* step = sensor.find(0x6005, 1)) cfg_.scaling.position_step_mm = step->asDouble() * 1e-6;
  clean_.scaling = cfg_.scaling;  // after the rest below too
  std::int64_t full = 0;
  if (const auto* c = valve.find(cfg_.command_index, cfg_.command_sub); c && c->highLimit(full) && full > 0)
    cfg_.scaling.command_full_counts = static_cast<double>(full);
  if (const auto* p = valve.find(cfg_.pressure_index, cfg_.pressure_sub); p && p->highLimit(full) && full > 0)
    cfg_.scaling.pressure_full_counts = static_cast<double>(full);
  clean_.scaling = cfg_.scaling;
}

void EmulatorNodes::start(TimeUs now) {
  for (auto& s : sensors_) s->start(now);
  valve_.node().start(now);
}

// Physics over the cycle that just ended, under the command held during it.
void EmulatorNodes::onSync() {
  const std::uint64_t k = ++syncs_;
  const double t = time();
  const double F = cfg_.payload_at_s >= 0 && t >= cfg_.payload_at_s ? cfg_.payload_N : 0.0;
  for (std::size_t c = 0; c < plants_.size(); ++c) {
    plants_[c].step(valve_.held(c), F);
    sensors_[c]->measured(k, t, cfg_.scaling.positionCounts(plants_[c].measure()));
    valve_.reportPressure(plants_[c].pressure_bar(), c);
  }
}

void EmulatorNodes::onFrame(const Frame& f, TimeUs now) {
  for (auto& s : sensors_) s->tick(now);
  const bool sync = (f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended();
  if (sync) onSync();
  for (auto& s : sensors_) s->onFrame(f, now);
  valve_.node().onFrame(f, now);
  // The valve latched the command of the last cycle at this SYNC: it holds until the next one.
  if (sync) valve_.update(now);
}

void EmulatorNodes::advance(TimeUs now) {
  for (auto& s : sensors_) {
    s->tick(now);
    s->advance(now);
  }
  valve_.node().advance(now);
}

TimeUs EmulatorNodes::nextDeadline() const {
  TimeUs t = valve_.node().nextDeadline();
  for (const auto& s : sensors_) t = std::min(t, s->nextDeadline());
  return t;
}

}  // namespace pamc::nodes
