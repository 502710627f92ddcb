#include "nodes/od_overrides.hpp"

namespace pamc::nodes {

void OdOverrides::apply(canopen::ObjectDictionary& od, ControllerParameters& params) {
  if (cfg_.kind >= 0) od.ref<std::uint8_t>(0x2010, 0).set(static_cast<std::uint8_t>(cfg_.kind));
  if (cfg_.gains_from_config) {
    params.writeGains(cfg_.ctrl);
    params.writeUkf(cfg_.ctrl.ukf);
  }
  params.writeModel(cfg_.ctrl.model.core());
  if (cfg_.has_trajectory) traj_override_ = !trajectoryToOd(od, cfg_.trajectory);
  if (cfg_.period_us) {
    od.ref<std::uint32_t>(0x1006, 0).set(cfg_.period_us);
    // The synchronous window keeps its share of the period (0x1007 default: 800 of 1000 us).
    if (auto* w = od.find(0x1007, 0)) w->set<std::uint32_t>(cfg_.period_us / 5 * 4);
  }
  if (!cfg_.produce_sync) {
    auto cob = od.ref<std::uint32_t>(0x1005, 0);
    cob.set(cob.get() & ~0x40000000u);  // consume SYNC from another master
  }
}

}  // namespace pamc::nodes
