#include <stdexcept>

#include "model/effect.hpp"
#include "model/probe.hpp"

namespace pamc::model {

#define PAMC_EFFECT(n) std::unique_ptr<Effect> make_##n();
#include "model/effects/catalogue.inc"
#undef PAMC_EFFECT

const std::vector<CatalogueEntry>& catalogue() {
  static const std::vector<CatalogueEntry> list = {
#define PAMC_EFFECT(n) {#n, &make_##n},
#include "model/effects/catalogue.inc"
#undef PAMC_EFFECT
  };
  return list;
}

std::string knownEffectNames() {
  std::string s;
  for (const auto& e : catalogue()) s += (s.empty() ? "" : ", ") + std::string(e.name);
  return s;
}

std::unique_ptr<Effect> makeEffect(const std::string& name) {
  for (const auto& e : catalogue())
    if (name == e.name) return e.make();
  if (const auto* p = findProbe(name)) return p->make();
  if (const std::string base = directionalBase(name); !base.empty()) return makeDirectional(makeEffect(base));
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + knownEffectNames() + ")");
}

}  // namespace pamc::model
