#include "model/probe.hpp"

namespace pamc::model {

#define PAMC_PROBE(n, meaning) std::unique_ptr<Effect> make_##n();
#include "model/probes/probes.inc"
#undef PAMC_PROBE

const std::vector<ProbeEntry>& probes() {
  static const std::vector<ProbeEntry> list = {
#define PAMC_PROBE(n, meaning) {#n, &make_##n, meaning},
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

std::string knownProbeNames() {
  std::string s;
  for (const auto& p : probes()) s += (s.empty() ? "" : ", ") + std::string(p.name);
  return s;
}

}  // namespace pamc::model
