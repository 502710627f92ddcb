#include "rig/rig_emulator.hpp"

#include <map>
#include <set>
#include <stdexcept>
#include <string>

namespace pamc::rig {

nodes::EmulatorConfig emulatorOf(const nodes::RigFile& rig, nodes::EmulatorConfig base) {
  if (rig.one_muscle_form) return base;  // its devices are pamc's own, or --profile-defaults's
  auto fail = [&](const std::string& why) -> void {
    throw std::invalid_argument(rig.path + ": the emulator cannot play this rig: " + why);
  };
  const auto& first = rig.channels[0];
  base.valve_eds = rig.slave(first.cfg.valve_id).eds;
  base.valve_id = first.cfg.valve_id;
  base.sensor_eds = rig.slave(first.cfg.sensor_id).eds;
  base.command_index = first.command.index;
  base.command_sub = first.command.sub;
  base.pressure_index = first.feedback.index != 0 ? first.feedback.index : base.pressure_index;
  base.pressure_sub = first.feedback.index != 0 ? first.feedback.sub : base.pressure_sub;
  base.position_index = first.position.index;
  base.position_sub = first.position.sub;
  base.muscles.sensor_ids.clear();
  base.muscles.valve_ids.clear();
  std::set<std::uint8_t> sensors;
  std::map<std::uint8_t, std::size_t> outputs;  // per valve slave: the outputs taken so far
  for (std::size_t c = 0; c < rig.channels.size(); ++c) {
    const auto& ch = rig.channels[c];
    const std::size_t o = outputs[ch.cfg.valve_id]++;
    if (!sensors.insert(ch.cfg.sensor_id).second && ch.cfg.position_object == 0) fail("a sensor serves two channels");
    if (rig.slave(ch.cfg.sensor_id).eds != base.sensor_eds) fail("its sensors have different EDS files");
    if (rig.slave(ch.cfg.valve_id).eds != base.valve_eds) fail("its valve modules have different EDS files");
    if (ch.command.index != base.command_index || ch.command.sub != base.command_sub + o)
      fail("channel " + std::to_string(c + 1) + " is not on the output after its module's last channel's");
    if (ch.feedback.index != 0 && ch.feedback.sub != base.pressure_sub + o)
      fail("channel " + std::to_string(c + 1) + "'s pressure input is not the one after its module's last channel's");
    base.muscles.sensor_ids.push_back(ch.cfg.sensor_id);
    base.muscles.valve_ids.push_back(ch.cfg.valve_id);
  }
  base.muscles.joints.clear();
  for (const auto& j : rig.joints) {
    nodes::EmulatorConfig::Muscles::Joint e;
    e.flexor = j.flexor, e.extensor = j.extensor;
    e.mech.lever_mm = j.lever_mm;
    e.mech.rest_mm = j.rest_mm;
    e.angle_step_deg = j.angle_step_deg;
    e.angle_zero_counts = j.angle_zero_counts;
    base.muscles.joints.push_back(e);
  }
  base.scaling = nodes::pd::Scaling{};  // the devices' own dictionaries say how they count
  return base;
}

}  // namespace pamc::rig
