// A plant's open-loop record as a measurement (tests/unit/test_mbc.cpp, test_probes.cpp): the command of an
// `--input` spec straight to the valve of the plant, as `pamc emulate` runs it, without the CSV between.
#pragma once

#include <string>

#include "control/trajectory.hpp"
#include "io/measurement.hpp"
#include "plant/plant.hpp"
#include "sim/lockstep.hpp"

namespace pamc::test {

inline io::Measurement openLoopRecord(const plant::PlantConfig& pc, const std::string& input, double seconds) {
  plant::Plant p(pc);
  const auto r = sim::runOpenLoopInput(p, control::Trajectory::parse(input), seconds);
  io::Measurement d;
  d.source = input;
  d.t = r.t;
  d.u = r.u;
  d.y = r.y;
  d.Ts = pc.Ts;
  return d;
}

}  // namespace pamc::test
