// Two muscles of one antagonistic joint, for the emulator: a flexor and an extensor on a pulley of
// radius `lever_mm`, joined by a cable (tendon) over it. The muscles pull against each other: the
// joint is their load, so each plant's payload keeps its mass, friction and damping but loses its
// weight and load spring, and the cable's tension - stiff, damped, never pushing - loads both. The
// joint's angle is the difference of the contractions over the lever, angle = (y_flexor - y_extensor) /
// (2 lever); their sum beyond 2 rest_mm stretches the cable: co-contraction raises the tension and with
// it the joint's stiffness. The joint's inertia is seen at each muscle's end as J / lever^2 / 2 (added to
// its payload's mass). Each muscle is a plant of its own (physics kind); the cable's force is taken
// from the last sample (a stiff spring coupled explicitly: for the defaults its frequency with the
// masses is about 14 Hz, 70 samples a period at 1 kHz, damped at about half its critical damping).
#pragma once

#include "plant/plant.hpp"

namespace pamc::plant {

struct JointConfig {
  double lever_mm = 25.0;         // pulley radius
  double rest_mm = 15.0;          // each muscle's contraction at angle 0 with the cable slack
  double cable_N_per_mm = 200.0;  // the cable's stiffness
  double cable_N_s_per_mm = 2.0;  // ... its damping
  double inertia_kg_m2 = 0.01;    // the link's inertia about the joint
};

class AntagonisticJoint {
 public:
  // Each plant gets the joint's inertia on its payload's mass; both must be of the physics kind
  // (std::invalid_argument otherwise).
  AntagonisticJoint(const JointConfig& cfg, PlantConfig flexor, PlantConfig extensor);
  void reset(double u0) noexcept;
  // One sample under the two commands held over it.
  void step(double u_flexor, double u_extensor) noexcept;
  double angleDeg() const noexcept;  // of the contractions now
  double tensionN() const noexcept { return tension_; }
  Plant& flexor() noexcept { return flexor_; }
  Plant& extensor() noexcept { return extensor_; }
  const JointConfig& config() const noexcept { return cfg_; }

 private:
  static PlantConfig withInertia(PlantConfig p, const JointConfig& j);
  double stretchMm() const noexcept;

  JointConfig cfg_;
  Plant flexor_, extensor_;
  double tension_ = 0.0;
  double stretch_last_ = 0.0;
};

}  // namespace pamc::plant
