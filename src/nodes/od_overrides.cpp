#include "nodes/od_overrides.hpp"

namespace pamc::nodes {

namespace {
std::uint32_t withNode(std::uint32_t hb, std::uint8_t id) { return (static_cast<std::uint32_t>(id) << 16) | (hb & 0xFFFFu); }
}  // namespace

void OdOverrides::apply(canopen::ObjectDictionary& od, ControllerParameters& params) {
  if (cfg_.kind >= 0) od.ref<std::uint8_t>(0x2010, 0).set(static_cast<std::uint8_t>(cfg_.kind));
  if (cfg_.gains_from_config) params.writeGains(cfg_.ctrl);
  params.writeModel(cfg_.ctrl.model.core());
  if (cfg_.has_trajectory) traj_override_ = !trajectoryToOd(od, cfg_.trajectory);
  if (cfg_.period_us) {
    od.ref<std::uint32_t>(0x1006, 0).set(cfg_.period_us);
    // The synchronous window keeps its share of the period (0x1007 default: 800 of 1000 us).
    if (auto* w = od.find(0x1007, 0)) w->set<std::uint32_t>(cfg_.period_us / 5 * 4);
  }
  // Where the slaves' process data are, and whose heartbeats to watch.
  const auto& lay = cfg_.layout;
  if (lay.sensor_cob) od.ref<std::uint32_t>(0x1400, 1).set(lay.sensor_cob);
  if (lay.feedback_cob) od.ref<std::uint32_t>(0x1401, 1).set(lay.feedback_cob);
  if (!lay.feedback) {
    auto cob = od.ref<std::uint32_t>(0x1401, 1);
    cob.set(cob.get() | 0x80000000u);  // no feedback PDO: RPDO2 off
  }
  if (lay.valve_cob) od.ref<std::uint32_t>(0x1800, 1).set(lay.valve_cob);
  for (auto [sub, id] : {std::pair<std::uint8_t, std::uint8_t>{1, cfg_.sensor_id}, {2, cfg_.valve_id}}) {
    auto hb = od.ref<std::uint32_t>(0x1016, sub);
    hb.set(withNode(hb.get(), id));
  }
  if (lay.startup) od.ref<std::uint32_t>(0x1F80, 0).set(lay.startup);
  // 0x1F81 for the slaves (the master reads it when it begins): the rig's boot settings, or a plain slave
  // (reset when it comes back after a heartbeat loss) for a node-ID the EDS does not assign.
  for (auto [id, boot] : {std::pair<std::uint8_t, const std::optional<canopen::SlaveBoot>*>{cfg_.sensor_id, &lay.sensor_boot},
                          {cfg_.valve_id, &lay.valve_boot}}) {
    auto* e = od.find(0x1F81, id);
    if (e == nullptr) continue;
    std::uint32_t a = e->get<std::uint32_t>();
    if (*boot) a = (*boot)->assignment;
    else if (a == 0) a = canopen::kAssignSlave;
    if (id == cfg_.sensor_id && lay.position_step_from_device) a |= canopen::kAssignBoot;
    e->set<std::uint32_t>(a);
  }
  if (!cfg_.produce_sync) {
    auto cob = od.ref<std::uint32_t>(0x1005, 0);
    cob.set(cob.get() & ~0x40000000u);  // consume SYNC from another master
  }
}

}  // namespace pamc::nodes
