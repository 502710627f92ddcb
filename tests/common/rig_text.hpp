// Rig files for tests: a shipped rig of od/rigs/ with lines replaced or added and its EDS paths made
// absolute, written to the test's own temporary file (ctest runs a file's tests at once); the
// controller a rig file makes, with the tests' PI on a sine, and pamc's own emulated devices.
#pragma once

#include <gtest/gtest.h>

#include <fstream>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "nodes/controller_config.hpp"
#include "nodes/emulator_config.hpp"
#include "nodes/rig_file.hpp"
#include "plant/plant.hpp"

namespace pamc::test {

inline const std::string kOd = std::string(PAMC_SOURCE_DIR) + "/od/";

using Edits = std::vector<std::pair<std::string, std::string>>;

// In the temporary directory, named after the test too.
inline std::string writeTemp(const std::string& name, const std::string& text) {
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const std::string path = ::testing::TempDir() + info->test_suite_name() + "." + info->name() + "." + name;
  std::ofstream(path) << text;
  return path;
}

// A rig file of the source tree (a path from its root) whose EDS paths are written as from od/rigs/,
// with each edit's first text replaced by its second (a missing one fails the test).
inline std::string rigText(const std::string& file, const Edits& edits = {}) {
  const std::string name = file;
  std::ifstream in(std::string(PAMC_SOURCE_DIR) + "/" + file);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  for (std::string::size_type at; (at = text.find("= ../")) != std::string::npos;) text.replace(at, 5, "= " + kOd);
  for (const auto& [from, to] : edits) {
    const auto at = text.find(from);
    if (at == std::string::npos) {
      ADD_FAILURE() << "no '" << from << "' in " << name;
      continue;
    }
    text.replace(at, from.size(), to);
  }
  return text;
}

// od/rigs/<name>, edited.
inline std::string shippedRig(const std::string& name, const Edits& edits = {}) {
  return rigText("od/rigs/" + name, edits);
}

// The one-muscle form ([sensor], [valve]) of od/rigs/default.ini, edited: tests/data/rigs/one_muscle.ini.
inline std::string oneMuscleRig(const Edits& edits = {}) { return rigText("tests/data/rigs/one_muscle.ini", edits); }

// The node rig makes, running PI (the emulator's true model) on a 0.2 Hz sine of 10-20 mm after 0.5 s;
// its boot reports into log.
inline nodes::ControllerNodeConfig rigController(const nodes::RigFile& rig, std::vector<std::string>* log = nullptr) {
  nodes::ControllerNodeConfig c;
  nodes::applyRig(rig, c);
  c.kind = static_cast<int>(control::Kind::PI);
  c.ctrl.model = plant::PlantConfig::modelDefaults().truth;
  c.has_trajectory = true;
  c.trajectory = control::Trajectory::sine(0.2, 5.0, 15.0);
  c.preroll_s = 0.5;
  if (log) c.log = [log](const std::string& m) { log->push_back(m); };
  return c;
}

// The emulator of pamc's own sensor and valve (od/sensor.eds, od/valve.eds).
inline nodes::EmulatorConfig pamcEmulator() {
  nodes::EmulatorConfig e;
  e.sensor_eds = kOd + "sensor.eds";
  e.valve_eds = kOd + "valve.eds";
  return e;
}

}  // namespace pamc::test
