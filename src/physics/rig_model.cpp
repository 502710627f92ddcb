// Mode rig: regulator, flow-limited fill and vent, muscle, braid friction, payload, end stops.
// Equations and parameter sources: docs/PHYSICS.md, section "Mode rig".
#include <algorithm>
#include <cmath>

#include "physics/dynamics.hpp"

namespace pamc::physics {

namespace {
constexpr double kPi = 3.14159265358979323846;
constexpr double kRhoAnr = 1.185;  // air density at ISO 8778 standard reference atmosphere [kg/m^3]
constexpr double kRAir = 287.05;   // specific gas constant of air [J/(kg K)]

// ISO 6358 flow function of the pressure ratio r = p_down / p_up: choked (1) below the critical
// ratio b, the elliptic subsonic law above it, and linear in the pressure difference above r_lam,
// where the elliptic law's slope would grow without bound (a stiffness no fixed step could follow).
double flowFunction(double r, double b, double r_lam) noexcept {
  if (r >= 1.0) return 0.0;
  if (r <= b) return 1.0;
  if (r > r_lam) {
    const double q = (r_lam - b) / (1.0 - b);
    return std::sqrt(1.0 - q * q) * (1.0 - r) / (1.0 - r_lam);
  }
  const double q = (r - b) / (1.0 - b);
  return std::sqrt(1.0 - q * q);
}
}  // namespace

RigModel::RigModel(const PhysicsConfig& c) : c_(&c) {
  const auto& g = c.regulator;
  const auto& m = c.muscle;
  const auto& l = c.payload;
  p_atm_ = g.atmosphere_bar * 1e5;
  p_sup_ = p_atm_ + g.supply_bar * 1e5;
  // The regulator cannot deliver more than its supply.
  p_set_max_ = std::min(p_sup_, p_atm_ + 10.0 * g.setpoint_bar_per_V * 1e5);
  c_rho0_ = g.conductance_dm3_per_s_bar * 1e-8 * kRhoAnr;  // dm^3/(s bar) -> m^3/(s Pa), times rho0
  band_Pa_ = g.band_bar * 1e5;
  rt_ = kRAir * g.temperature_K;
  const double r0 = 0.5 * m.diameter_mm * 1e-3;
  geo_.area = kPi * r0 * r0;
  geo_.len = m.length_mm * 1e-3;
  const double th = m.braid_angle_deg * kPi / 180.0;
  geo_.cos2 = std::cos(th) * std::cos(th);
  const double sin2 = 1.0 - geo_.cos2;
  geo_.a = 3.0 * geo_.cos2 / sin2;  // 3 / tan^2 theta0
  geo_.b = 1.0 / sin2;              // 1 / sin^2 theta0
  geo_.vol0 = geo_.area * geo_.len;
  vol_dead_ = g.dead_volume_cm3 * 1e-6;
  k_rubber_ = m.rubber_N_per_mm * 1e3;
  k_load_ = l.spring_N_per_mm * 1e3;
  hyst_.h0 = m.hysteresis_N;
  hyst_.per_Pa = m.hysteresis_N_per_bar * 1e-5;
  hyst_.delta = m.hysteresis_travel_mm * 1e-3;
  mass_ = l.mass_kg;
  weight_ = l.mass_kg * l.gravity_m_per_s2 + l.spring_preload_N;
  coul_v_ = l.coulomb_velocity_mm_per_s * 1e-3;
  y_min_ = c.stroke_min_mm * 1e-3;
  y_max_ = c.stroke_max_mm * 1e-3;
}

double RigModel::setpoint_Pa(double cmd) const noexcept {
  const double v = std::clamp(c_->regulator.setpoint_offset_V + cmd, 0.0, 10.0);
  return std::min(p_atm_ + v * c_->regulator.setpoint_bar_per_V * 1e5, p_set_max_);
}

// Tondu-Lopez: F = p_gauge pi r0^2 (a (1 - k eps)^2 - b), minus the rubber's elastic force.
double RigModel::muscleForce(double p_abs, double y) const noexcept {
  const double s = 1.0 - c_->muscle.tondu_k * (y / geo_.len);
  return geo_.area * (p_abs - p_atm_) * (geo_.a * s * s - geo_.b) - k_rubber_ * y;
}

// Net static force on the payload in the contraction direction, at rest (no friction).
double RigModel::staticForce(double p_abs, double y, double force_N) const noexcept {
  return muscleForce(p_abs, y) - weight_ - k_load_ * y - force_N;
}

void RigModel::rhs(const PhysicsState& x, PhysicsState& dx, double cmd, double force_N) const noexcept {
  const auto& g = c_->regulator;
  dx.fill(0.0);
  const double p = std::max(x[kP], 1.0);
  const double xv = x[kXv];
  // The regulator's valve opening follows its pressure error (saturated) with a first-order lag.
  dx[kXv] = (std::clamp((setpoint_Pa(cmd) - p) / band_Pa_, -1.0, 1.0) - xv) / g.tau_s;
  // Mass flow through the opened fraction of the path: supply -> muscle, or muscle -> atmosphere.
  double mdot = 0.0;
  if (xv > 0.0)
    mdot = xv * c_rho0_ * p_sup_ * flowFunction(p / p_sup_, g.critical_ratio, g.laminar_ratio);
  else if (xv < 0.0)
    mdot = xv * c_rho0_ * p * flowFunction(p_atm_ / p, g.critical_ratio, g.laminar_ratio);

  const double y = x[kY], v = x[kYd];
  const double p_gauge = p - p_atm_;
  const double hyst = (hyst_.h0 + hyst_.per_Pa * std::max(p_gauge, 0.0)) * x[kZh];
  double f = muscleForce(p, y) - hyst - weight_ - k_load_ * y - force_N - c_->payload.viscous_N_s_per_m * v -
             c_->payload.coulomb_N * std::tanh(v / coul_v_);
  // Against a stop the stop's reaction balances a force into it: the payload rests there.
  double v_eff = v;
  if (c_->stroke_limits && ((y <= y_min_ && v <= 0.0 && f <= 0.0) || (y >= y_max_ && v >= 0.0 && f >= 0.0))) {
    v_eff = 0.0;
    f = 0.0;
  }
  dx[kY] = v_eff;
  dx[kYd] = v_eff == 0.0 && f == 0.0 ? 0.0 : f / mass_;

  // Geometric volume of the braid (Tondu's cylinder), dV/dy = pi r0^2 (a s^2 - b) with s = 1 - eps.
  const double s = 1.0 - y / geo_.len;
  const double vol =
      std::max(geo_.vol0 * s * (1.0 - geo_.cos2 * s * s) / (1.0 - geo_.cos2), 0.2 * geo_.vol0) + vol_dead_;
  const double dvol_dy = geo_.area * (geo_.a * s * s - geo_.b);
  dx[kP] = g.polytropic_index / vol * (rt_ * mdot - p * dvol_dy * v_eff);
  // Dahl friction of the braid, rate-independent in the contraction: dz/dy = (1 - sgn(dy) z) / delta.
  dx[kZh] = (v_eff - std::fabs(v_eff) * x[kZh]) / hyst_.delta;
  if (c_->effects.creep.enabled)
    dx[kCreepR] = (c_->effects.creep.fraction * y * 1e3 - x[kCreepR]) / c_->effects.creep.tau;
}

void RigModel::rest(PhysicsState& x, double cmd, double force_N) const noexcept {
  x.fill(0.0);
  const double p = setpoint_Pa(cmd);
  x[kP] = p;
  double lo = c_->stroke_limits ? y_min_ : -0.1 * geo_.len;
  double hi = c_->stroke_limits ? y_max_ : 0.45 * geo_.len;
  double y;
  // The net force falls with the contraction: bisect to the equilibrium, or rest on a stop.
  if (staticForce(p, lo, force_N) <= 0.0) {
    y = lo;
  } else if (staticForce(p, hi, force_N) >= 0.0) {
    y = hi;
  } else {
    for (int i = 0; i < 200; ++i) {
      const double mid = 0.5 * (lo + hi);
      if (mid <= lo || mid >= hi) break;
      (staticForce(p, mid, force_N) > 0.0 ? lo : hi) = mid;
    }
    y = std::fabs(staticForce(p, lo, force_N)) < std::fabs(staticForce(p, hi, force_N)) ? lo : hi;
  }
  x[kY] = y;
  if (c_->effects.creep.enabled) x[kCreepR] = c_->effects.creep.fraction * y * 1e3;
}

void RigModel::project(PhysicsState& x) const noexcept {
  if (!c_->stroke_limits) return;
  if (x[kY] < y_min_) {
    x[kY] = y_min_;
    x[kYd] = std::max(x[kYd], 0.0);
  } else if (x[kY] > y_max_) {
    x[kY] = y_max_;
    x[kYd] = std::min(x[kYd], 0.0);
  }
}

}  // namespace pamc::physics
