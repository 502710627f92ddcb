// The plant emulator: what `pamc emulate`, the emulator node, the in-process rig and the paper's
// experiments run against. Two kinds, named in the plant file's "kind":
//  - "physics" (the default): the independent continuous-time simulation of the rig in src/physics
//    (pressure regulator, muscle force map, braid friction, payload, end stops, sensor), which shares no
//    code with the model it is used to judge (docs/PHYSICS.md);
//  - "model": the PAM model itself (Bouc-Wen core plus physical effects from the catalogue) with the parts
//    only a rig has - stroke limits, a pressure reading, sensor noise and 0.001 mm quantisation - for
//    tests that need data of a known structure in the model's own terms (docs/CALIBRATION.md);
//  - external, set by a harness and never by a plant file: dynamics from outside the library (the test
//    oracle's simulator in tests/oracle, which shares no code with pamc), stepped where the physics plant
//    would be, so the experiments run unchanged on a second, independent plant.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "model/model.hpp"
#include "physics/physics_plant.hpp"

namespace pamc::plant {

enum class PlantKind { Physics, Model, External };
const char* plantKindName(PlantKind k) noexcept;

// The dynamics of a plant of kind external. Plant hands it a finite command within the valve's range.
class ExternalDynamics {
 public:
  virtual ~ExternalDynamics() = default;
  // At rest under the command u0 [V] and the external force [N].
  virtual void reset(double u0, double force_N) noexcept = 0;
  // Holds u for one sample under the force; the true position at the end of the sample [mm].
  virtual double step(double u, double force_N) noexcept = 0;
  // The true position now [mm], and what its sensor reads of it.
  virtual double position() const noexcept = 0;
  virtual double measure() noexcept = 0;
  virtual double pressure_bar() const noexcept { return NAN; }
};
struct ExternalPlant {
  std::string name;  // how summaries name the plant
  // A fresh, independent instance stepped at Ts [s]; called once per Plant (runs may be in parallel).
  std::function<std::unique_ptr<ExternalDynamics>(double Ts)> make;
};

struct PlantConfig {
  PlantKind kind = PlantKind::Physics;
  // Kind physics: the whole configuration of the continuous-time plant. Ts is the sample time the plant
  // is stepped at for either kind (a bus with another SYNC period sets it); the physics plant's own
  // Ts, command range, sensor and seed are read into the fields below when a file is read.
  physics::PhysicsConfig physics;
  double Ts = 1e-3;  // sample time [s]
  // Kind model:
  model::Model truth;  // core + effects
  bool stroke_limits = true;
  double stroke_min_mm = 0.0;
  double stroke_max_mm = 40.0;
  bool sensor_noise = true;
  double noise_std_mm = 0.004;
  bool quantization = true;
  double quantum_mm = 0.001;
  double u_min = -5.0, u_max = 5.0;  // valve command range [V] (valve voltage = 5 V + u)
  double pressure_max_bar = 8.0;     // regulator output at the top of the range
  std::uint64_t seed = 1;
  // Kind external (the command range above applies to it too):
  ExternalPlant external;

  // The default plant: the physics plant with its defaults.
  static PlantConfig defaults();
  // Kind model with its built-in defaults (today's emulator, calibrated in docs/CALIBRATION.md).
  static PlantConfig modelDefaults();
  // The defaults of the kind the document names ("kind": "physics" when it names none) overridden by
  // it; throws std::invalid_argument naming the bad key.
  static PlantConfig fromJson(const nlohmann::json& j, const std::string& where);
  static PlantConfig fromFile(const std::string& path);
  nlohmann::json toJson() const;
};

class Plant {
 public:
  explicit Plant(const PlantConfig& cfg = PlantConfig::defaults());
  const PlantConfig& config() const { return cfg_; }

  // At rest under the command u0 [V] and external force [N].
  void reset(double u0, double force_N = 0.0) noexcept;
  // Holds the valve command u [V] for one sample under the external force, returns the true
  // position at the end of the sample [mm].
  double step(double u, double force_N = 0.0) noexcept;
  // What the position sensor reads now (noise, quantisation) [mm].
  double measure() noexcept;
  double position() const noexcept { return physics_ ? physics_->position() : external_ ? external_->position() : y_; }
  // Muscle pressure: the physics plant's; the model's effective command after the input effects, scaled
  // to the regulator.
  double pressure_bar() const noexcept;

 private:
  double validCommand(double u) const noexcept;  // finite, within the valve's range

  PlantConfig cfg_;
  std::unique_ptr<physics::PhysicsPlant> physics_;  // kind physics
  std::unique_ptr<ExternalDynamics> external_;      // kind external
  model::Model::State st_;
  double y_ = 0.0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
};

}  // namespace pamc::plant
