#include "plant/joint.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pamc::plant {

PlantConfig AntagonisticJoint::withInertia(PlantConfig p, const JointConfig& j) {
  if (p.kind != PlantKind::Physics)
    throw std::invalid_argument("joint: its muscles must be plants of the physics kind");
  const double r = j.lever_mm * 1e-3;
  p.physics.payload.mass_kg += j.inertia_kg_m2 / (r * r) / 2.0;
  p.physics.payload.gravity_m_per_s2 = 0.0;  // the other muscle is the load, through the cable
  p.physics.payload.spring_preload_N = 0.0;
  p.physics.payload.spring_N_per_mm = 0.0;
  return p;
}

AntagonisticJoint::AntagonisticJoint(const JointConfig& cfg, PlantConfig flexor, PlantConfig extensor)
    : cfg_(cfg), flexor_(withInertia(std::move(flexor), cfg)), extensor_(withInertia(std::move(extensor), cfg)) {
  if (!(cfg.lever_mm > 0) || !(cfg.cable_N_per_mm > 0))
    throw std::invalid_argument("joint: lever and cable stiffness must be above 0");
}

void AntagonisticJoint::reset(double u0) noexcept {
  flexor_.reset(u0, 0.0);
  extensor_.reset(u0, 0.0);
  stretch_last_ = stretchMm();
  tension_ = 0.0;
}

double AntagonisticJoint::stretchMm() const noexcept {
  return flexor_.position() + extensor_.position() - 2.0 * cfg_.rest_mm;
}

void AntagonisticJoint::step(double u_flexor, double u_extensor) noexcept {
  const double s = stretchMm();
  const double rate = (s - stretch_last_) / flexor_.config().Ts;  // mm/s
  stretch_last_ = s;
  tension_ = std::max(0.0, cfg_.cable_N_per_mm * s + cfg_.cable_N_s_per_mm * rate);
  flexor_.step(u_flexor, tension_);
  extensor_.step(u_extensor, tension_);
}

double AntagonisticJoint::angleDeg() const noexcept {
  return (flexor_.position() - extensor_.position()) / (2.0 * cfg_.lever_mm) * 180.0 / M_PI;
}

}  // namespace pamc::plant
