#include "nodes/emulator_node.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pamc::nodes {

using canopen::Frame;
using canopen::TimeUs;

EmulatorNodes::EmulatorNodes(const EmulatorConfig& cfg, canopen::Transport& transport) : cfg_(cfg), clean_(cfg) {
  clean_.sensor_silent_at_s = -1, clean_.drop_pdo_prob = 0.0, clean_.late_pdo_cycles = 0;
  if (cfg_.fault_channel >= cfg_.channels()) throw std::invalid_argument("emulator: fault channel beyond the channels");
  addValves(transport);
  addPlants();
  addSensors(transport);
  scalingFromDevices();
  sync_cob_ = sensors_[0]->node().od().ref<std::uint32_t>(0x1005, 0).get() & 0x7FFu;
  // The valve holds its command at 0 V (vented) until the controller sends one.
  for (auto& p : plants_) p->reset(pd::kCommandMin, 0.0);  // vented: 0 V at the valve
  for (auto& j : joints_) j->reset(pd::kCommandMin);
  for (std::size_t s = 0; s < sensors_.size(); ++s) sensors_[s]->measured(0, 0.0, counts(s, false));
}

// A plant per muscle - each its own noise (seed + channel) - the joints' pairs in their joints.
void EmulatorNodes::addPlants() {
  const std::size_t n = cfg_.channels();
  joint_of_.assign(n, -1);
  plant_of_.assign(n, nullptr);
  auto own = [&](std::size_t c) {
    plant::PlantConfig pc = cfg_.plant;
    pc.seed += c;
    pc.physics.seed += c;
    return pc;
  };
  for (std::size_t j = 0; j < cfg_.muscles.joints.size(); ++j) {
    const auto& jc = cfg_.muscles.joints[j];
    if (jc.flexor >= n || jc.extensor >= n || jc.flexor == jc.extensor || joint_of_[jc.flexor] >= 0 ||
        joint_of_[jc.extensor] >= 0)
      throw std::invalid_argument("emulator: joint " + std::to_string(j + 1) +
                                  " is not two channels of no other joint");
    joints_.push_back(std::make_unique<plant::AntagonisticJoint>(jc.mech, own(jc.flexor), own(jc.extensor)));
    joint_of_[jc.flexor] = joint_of_[jc.extensor] = static_cast<int>(j);
    plant_of_[jc.flexor] = &joints_.back()->flexor();
    plant_of_[jc.extensor] = &joints_.back()->extensor();
  }
  for (std::size_t c = 0; c < n; ++c) {
    if (plant_of_[c] != nullptr) continue;
    plants_.push_back(std::make_unique<plant::Plant>(own(c)));
    plant_of_[c] = plants_.back().get();
  }
}

// A sensor node per node-ID the channels name (a joint's two channels share its angle encoder).
void EmulatorNodes::addSensors(canopen::Transport& transport) {
  std::vector<std::uint8_t> ids;
  for (std::size_t c = 0; c < cfg_.channels(); ++c) {
    const std::uint8_t id = cfg_.muscles.sensor_ids.empty() ? cfg_.sensor_id : cfg_.muscles.sensor_ids[c];
    const auto at = std::find(ids.begin(), ids.end(), id);
    sensor_of_.push_back(static_cast<std::size_t>(at - ids.begin()));
    if (at != ids.end()) continue;
    ids.push_back(id);
    sensor_joint_.push_back(joint_of_[c]);
    sensor_channel_.push_back(c);
  }
  const std::size_t faulty = sensor_of_[cfg_.fault_channel];
  for (std::size_t s = 0; s < ids.size(); ++s)
    sensors_.push_back(
        std::make_unique<EmulatedSensor>(s == faulty ? cfg_ : clean_, transport, s == faulty ? inj_ : none_, ids[s]));
}

// A muscle's encoder: its position; a joint's: its angle. measured: as its sensor measures it (noise),
// else the true position.
std::int32_t EmulatorNodes::counts(std::size_t s, bool measured) noexcept {
  auto at = [measured](plant::Plant& p) { return measured ? p.measure() : p.position(); };
  if (sensor_joint_[s] < 0) return cfg_.scaling.positionCounts(at(*plant_of_[sensor_channel_[s]]));
  const auto& jc = cfg_.muscles.joints[static_cast<std::size_t>(sensor_joint_[s])];
  auto& j = *joints_[static_cast<std::size_t>(sensor_joint_[s])];
  const double deg = (at(j.flexor()) - at(j.extensor())) / (2.0 * jc.mech.lever_mm) * 180.0 / M_PI;
  return static_cast<std::int32_t>(std::lround(jc.angle_zero_counts + deg / jc.angle_step_deg));
}

// The valve modules in the order the channels name them; a channel on its module's next output.
void EmulatorNodes::addValves(canopen::Transport& transport) {
  std::vector<std::uint8_t> ids, outputs;
  for (std::size_t c = 0; c < cfg_.channels(); ++c) {
    const std::uint8_t id = cfg_.muscles.valve_ids.empty() ? cfg_.valve_id : cfg_.muscles.valve_ids.at(c);
    const auto at = std::find(ids.begin(), ids.end(), id);
    module_.push_back(static_cast<std::size_t>(at - ids.begin()));
    if (at == ids.end()) ids.push_back(id), outputs.push_back(0);
    output_.push_back(outputs[module_.back()]++);
  }
  for (std::size_t m = 0; m < ids.size(); ++m)
    valves_.push_back(std::make_unique<EmulatedValve>(cfg_, transport, inj_, ids[m], outputs[m]));
}

void EmulatorConfig::useProfileDevices(const std::string& od_dir) {
  sensor_eds = od_dir + "/profile/encoder406.eds";
  valve_eds = od_dir + "/profile/analog401.eds";
  sensor_id = valve_id = 0;  // theirs: 16 and 32
  position_index = 0x6004, position_sub = 0;
  command_index = 0x6411, command_sub = 2;    // the valve on output 2
  pressure_index = 0x6401, pressure_sub = 2;  // the pressure sensor on input 2
  scaling = pd::Scaling{};                    // what the devices' dictionaries say replaces it (scalingFromDevices)
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
  auto& valve = valves_[0]->node().od();
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
  for (auto& v : valves_) v->node().start(now);
}

// Physics over the cycle that just ended, under the command held during it.
void EmulatorNodes::onSync() {
  const std::uint64_t k = ++syncs_;
  const double t = time();
  const double F = cfg_.payload.at_s >= 0 && t >= cfg_.payload.at_s ? cfg_.payload.N : 0.0;
  auto held = [this](std::size_t c) { return valves_[module_[c]]->held(output_[c]); };
  for (std::size_t j = 0; j < joints_.size(); ++j)
    joints_[j]->step(held(cfg_.muscles.joints[j].flexor), held(cfg_.muscles.joints[j].extensor));
  for (std::size_t c = 0; c < plant_of_.size(); ++c)
    if (joint_of_[c] < 0) plant_of_[c]->step(held(c), F);
  for (std::size_t s = 0; s < sensors_.size(); ++s) sensors_[s]->measured(k, t, counts(s));
  for (std::size_t c = 0; c < plant_of_.size(); ++c)
    valves_[module_[c]]->reportPressure(plant_of_[c]->pressure_bar(), output_[c]);
}

void EmulatorNodes::onFrame(const Frame& f, TimeUs now) {
  for (auto& s : sensors_) s->tick(now);
  const bool sync = (f.id & 0x7FFu) == sync_cob_ && !f.remote() && !f.error() && !f.extended();
  if (sync) onSync();
  for (auto& s : sensors_) s->onFrame(f, now);
  for (auto& v : valves_) v->node().onFrame(f, now);
  // The valve latched the command of the last cycle at this SYNC: it holds until the next one.
  if (sync)
    for (auto& v : valves_) v->update(now);
}

void EmulatorNodes::advance(TimeUs now) {
  for (auto& s : sensors_) {
    s->tick(now);
    s->advance(now);
  }
  for (auto& v : valves_) v->node().advance(now);
}

TimeUs EmulatorNodes::nextDeadline() const {
  TimeUs t = canopen::kNever;
  for (const auto& v : valves_) t = std::min(t, v->node().nextDeadline());
  for (const auto& s : sensors_) t = std::min(t, s->nextDeadline());
  return t;
}

}  // namespace pamc::nodes
