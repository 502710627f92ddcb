// Emulator records for the modelling tests: the plain Bouc-Wen core plus the effects a test hides,
// noise and quantisation on, excited by random ramps and holds.
#pragma once

#include <string>

#include <nlohmann/json.hpp>

#include "control/trajectory.hpp"
#include "io/measurement.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

namespace pamc::testdata {

// The emulator with its default effects off and no end stops; `core_json` overrides the core's
// parameters, `effects_json` (JSON members, may be empty) switches effects on.
inline plant::PlantConfig plainPlantWith(const std::string& core_json, const std::string& effects_json) {
  std::string j =
      R"({"kind":"model","effects":{"pressure_lag":{"enabled":false},"load":{"enabled":false},"saturation":{"enabled":false},
    "friction_hysteresis":{"enabled":false},"mass_spring":{"enabled":false})";
  if (!effects_json.empty()) j += "," + effects_json;
  j += R"(},"stroke":{"enabled":false},"core":)" + core_json + "}";
  return plant::PlantConfig::fromJson(nlohmann::json::parse(j), "test");
}

// `seconds` of random ramps and holds over [lo, hi] from `seed`; with_load adds a random 0-40 N load
// (seed + 100) and its column.
inline io::Measurement emulatorRecord(const plant::PlantConfig& pc, std::uint64_t seed, double seconds,
                                      bool with_load = false, double lo = -2.5, double hi = 2.5) {
  plant::Plant p(pc);
  const auto u = control::Trajectory::randomRampHold(seed, lo, hi);
  const auto f = control::Trajectory::randomRampHold(seed + 100, 0.0, 40.0);
  const auto r = sim::runOpenLoopInput(p, u, seconds, with_load ? &f : nullptr);
  io::Measurement m;
  m.source = "emulator seed " + std::to_string(seed);
  m.t = r.t;
  m.u = r.u;
  m.y = r.y;
  m.Ts = r.t[1] - r.t[0];
  if (with_load) m.extra["load"] = r.force;
  return m;
}

}  // namespace pamc::testdata
