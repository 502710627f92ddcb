// The plant emulator: a PAM truth model built from the same model code as everything else
// (Bouc-Wen core plus physical effects), with the parts only a real rig has: hard stroke limits,
// a pressure reading, sensor noise and 0.001 mm quantisation. Every effect is on or off with its
// parameters from a JSON config file; the defaults are calibrated (docs/CALIBRATION.md) so that
// a Bouc-Wen fit is imperfect the way the paper's is.
#pragma once

#include <cstdint>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

#include "model/model.hpp"

namespace pamc::plant {

struct PlantConfig {
  double Ts = 1e-3;             // integration step = sample time [s]
  model::Model truth;           // core + effects
  bool stroke_limits = true;
  double stroke_min_mm = 0.0;
  double stroke_max_mm = 40.0;
  bool sensor_noise = true;
  double noise_std_mm = 0.004;
  bool quantization = true;
  double quantum_mm = 0.001;
  double u_min = -5.0, u_max = 5.0;   // valve command range [V] (valve voltage = 5 V + u)
  double pressure_max_bar = 8.0;      // regulator output at the top of the range
  std::uint64_t seed = 1;

  static PlantConfig defaults();
  // Defaults overridden by a JSON document; throws std::invalid_argument naming the bad key.
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
  double position() const noexcept { return y_; }
  // Muscle pressure: the effective command after the input effects, scaled to the regulator.
  double pressure_bar() const noexcept;

 private:
  PlantConfig cfg_;
  model::Model::State st_;
  double y_ = 0.0;
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
};

}  // namespace pamc::plant
