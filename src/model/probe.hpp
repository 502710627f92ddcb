// Probes: generic, non-physical structures that diagnose fits like effects when no effect of the
// catalogue brings the error down to the sensor noise. A probe that explains much of what is left
// says what *kind* of physics is missing (a curved characteristic, a drift in time, extra dynamics);
// it is never part of a physical model that diagnose proposes.
//
// Probes implement the Effect interface, so a model can carry one for a fit (makeEffect finds them);
// src/model/probes/probes.inc lists them, one line each with what a probe that helps points to.
#pragma once

#include <string>
#include <vector>

#include "model/effect.hpp"

namespace pamc::model {

struct ProbeEntry {
  const char* name;
  EffectFactory make;
  const char* meaning;  // the kind of physics a probe that helps points to, in words
  // The catalogue effects whose place it may take, comma-separated (probes.inc, second column); their
  // direction-dependent versions ("<effect>_updown") too.
  const char* stands_for;
  bool standsFor(const std::string& effect) const;
};

const std::vector<ProbeEntry>& probes();
// The probe of that name, or nullptr.
const ProbeEntry* findProbe(const std::string& name);
std::string knownProbeNames();

}  // namespace pamc::model
