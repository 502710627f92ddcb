// The right-hand sides of the two modes' ODEs (docs/PHYSICS.md): state derivatives for a command held
// constant and an external force, and the rest state for a constant command. Internal to src/physics.
#pragma once

#include "physics/physics_plant.hpp"

namespace pamc::physics {

// State indices, mode rig (SI units inside).
enum RigIndex : int {
  kP = 0,   // muscle pressure, absolute [Pa]
  kXv,      // regulator valve opening [-1, 1] (+ fills from supply, - vents)
  kY,       // contraction [m]
  kYd,      // contraction velocity [m/s]
  kZh,      // braid friction (Dahl) state [-1, 1]
  kCreepR,  // creep displacement [mm] (effect creep)
};

// State indices, mode reference (V and mm).
enum RefIndex : int {
  kV0 = 0,  // fast valve stage [V]
  kPl,      // pressure_lag's command [V]
  kH,       // Bouc-Wen hysteresis [V when alpha = 1]
  kFf,      // external force through the fast stage [N]
  kZa,      // asymmetry's element [V]
  kZc,      // creep [mm]
  kZf,      // friction_hysteresis [mm]
  kMy,      // mass_spring / force_loop position [mm]
  kMyd,     // ... velocity [mm/s]
  kFz,      // force_loop friction [mm]
};

class RigModel {
 public:
  explicit RigModel(const PhysicsConfig& c);
  // dx/dt for the held command cmd [V] (after delay and dead band) and external force [N].
  void rhs(const PhysicsState& x, PhysicsState& dx, double cmd, double force_N) const noexcept;
  // At rest under cmd and force: regulated pressure, valve closed, static equilibrium of the payload.
  void rest(PhysicsState& x, double cmd, double force_N) const noexcept;
  // End stops after a substep: a contact is inelastic (position clamped, velocity into the stop zeroed).
  void project(PhysicsState& x) const noexcept;
  // Contraction [mm] before the output effects.
  double contraction_mm(const PhysicsState& x) const noexcept { return x[kY] * 1e3; }
  double pressure_bar(const PhysicsState& x) const noexcept { return (x[kP] - p_atm_) * 1e-5; }
  double setpoint_Pa(double cmd) const noexcept;  // absolute

 private:
  double muscleForce(double p_abs, double y) const noexcept;
  double staticForce(double p_abs, double y, double force_N) const noexcept;

  // The muscle's geometry at rest (Tondu-Lopez): cross-section [m^2], length [m], the braid's
  // a = 3 / tan^2 theta0, b = 1 / sin^2 theta0 and cos^2 theta0, and the braid's volume [m^3].
  struct Geometry {
    double area, len, a, b, cos2, vol0;
  };
  // The braid's Dahl friction: its amplitude at zero gauge pressure [N], its growth with pressure
  // [N/Pa], and the travel over which it builds up [m].
  struct Hysteresis {
    double h0, per_Pa, delta;
  };

  const PhysicsConfig* c_;
  double p_atm_, p_sup_, p_set_max_, c_rho0_, band_Pa_, vol_dead_, rt_;
  Geometry geo_;
  double k_rubber_, k_load_;
  Hysteresis hyst_;
  double mass_, weight_, coul_v_;
  double y_min_, y_max_;
};

// What drives mode reference over a piece of a sample in which the command and the force are held: the
// fast first-order stages of both (time constant tau_valve_s) are linear with a known solution, so they
// enter the ODE as exact functions of time, v0(t) = cmd + (v0_start - cmd) exp(-(t - t_start) / tau).
struct ReferenceDrive {
  double cmd, v0_start, force, f_start, t_start;
};

class ReferenceModel {
 public:
  explicit ReferenceModel(const PhysicsConfig& c);
  // dx/dt at time t within the piece driven by d.
  void rhs(const PhysicsState& x, PhysicsState& dx, const ReferenceDrive& d, double t) const noexcept;
  // The fast stages' exact values at time t (written into x[kV0], x[kFf]).
  void setFastStages(PhysicsState& x, const ReferenceDrive& d, double t) const noexcept;
  // The first substep [in tau_valve_s] along a transient of the fast stages of the given size (0: none):
  // short enough that the rate-independent elements (Bouc-Wen core, asymmetry, friction_hysteresis),
  // whose time-stiffness grows with the speed of their input, move by a small fraction of their own
  // scale, and the exponential's quadrature error stays far below the sensor noise (docs/PHYSICS.md).
  double transientStepCommand(double dv_V) const noexcept;
  double transientStepForce(double df_N) const noexcept;
  void rest(PhysicsState& x, double cmd, double force_N) const noexcept;
  // The output chain (core, then the output effects up to warm_up) at state x [mm].
  double output(const PhysicsState& x) const noexcept;
  // The effective command v [V] (the Bouc-Wen core's input).
  double effectiveCommand(const PhysicsState& x) const noexcept;

 private:
  // The chain's value at x; with dx it also writes the output effects' derivatives (it needs the
  // derivative of the stage input, dY/dt, which the core's and upstream derivatives give); with
  // rest it puts the output effects' states at rest for their stage inputs (writing into *rest).
  double chain(const PhysicsState& x, PhysicsState* dx, PhysicsState* rest) const noexcept;

  const PhysicsConfig* c_;
  double wn_ms_, wn_fl_;                          // rad/s
  double stiff_per_V_ = 0.0, stiff_per_N_ = 0.0;  // of the rate-independent elements, per unit input travel
};

}  // namespace pamc::physics
