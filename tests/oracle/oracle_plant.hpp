// The oracle's simulator as a plant of kind external (plant::ExternalDynamics), where the oracle and pamc
// meet: pamc_oracle_experiments and the closed-loop tests. The oracle library stays free of pamc.
#pragma once

#include <memory>

#include "oracle_sim.hpp"
#include "plant/plant.hpp"

namespace pamc::oracle {

// The oracle's chain as the plant's dynamics; the oracle's load column is the payload's force [N].
class OracleDynamics final : public plant::ExternalDynamics {
 public:
  OracleDynamics(const Case& c, double Ts) : stepper_(c.core, c.effects, options(c, Ts)) {}

  void reset(double u0, double force_N) noexcept override {
    stepper_.reset(u0, force_N);
    measured_ = stepper_.clean();
  }
  double step(double u, double force_N) noexcept override {
    measured_ = stepper_.step(u, force_N);  // u is finite: Plant hands over a valid command
    return stepper_.clean();
  }
  double position() const noexcept override { return stepper_.clean(); }
  double measure() noexcept override { return measured_; }

  // The case's noise, stepped at Ts; the other options the oracle's defaults.
  static SimOptions options(const Case& c, double Ts) {
    SimOptions o;
    o.Ts = Ts;
    o.noise_std = c.noise_std;
    return o;
  }

 private:
  Stepper stepper_;
  double measured_ = 0.0;
};

// The case as a plant: the model plant's command range and sample time, the oracle's dynamics.
inline plant::PlantConfig oraclePlant(const Case& c) {
  plant::PlantConfig p = plant::PlantConfig::modelDefaults();
  p.kind = plant::PlantKind::External;
  p.external.name = "test oracle, case " + c.name + " (" + c.description + ")";
  p.external.make = [c](double Ts) { return std::make_unique<OracleDynamics>(c, Ts); };
  return p;
}

}  // namespace pamc::oracle
