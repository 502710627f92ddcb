#include "model/probe.hpp"

namespace pamc::model {

#define PAMC_PROBE(n, stands_for, meaning) std::unique_ptr<Effect> make_##n();
#include "model/probes/probes.inc"
#undef PAMC_PROBE

const std::vector<ProbeEntry>& probes() {
  static const std::vector<ProbeEntry> list = {
#define PAMC_PROBE(n, stands_for, meaning) {#n, &make_##n, meaning, stands_for},
#include "model/probes/probes.inc"
#undef PAMC_PROBE
  };
  return list;
}

const ProbeEntry* findProbe(const std::string& name) {
  for (const auto& p : probes())
    if (name == p.name) return &p;
  return nullptr;
}

// An effect's direction-dependent version ("pressure_lag_updown", taken by diagnose's directions step) is
// the same physics with more freedom: a probe that may take the effect's place may take its version's.
bool ProbeEntry::standsFor(const std::string& effect) const {
  const std::string updown_base = directionalBase(effect);
  const std::string base = updown_base.empty() ? effect : updown_base;
  const std::string list = std::string(",") + stands_for + ",";
  return !base.empty() && list.find("," + base + ",") != std::string::npos;
}

std::string knownProbeNames() {
  std::string s;
  for (const auto& p : probes()) s += (s.empty() ? "" : ", ") + std::string(p.name);
  return s;
}

}  // namespace pamc::model
