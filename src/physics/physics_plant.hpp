// An independent continuous-time plant of the PAM rig, for tests that need an oracle sharing no code
// with the model (src/model) it checks. Two modes:
//  - "rig": the rig's physics - a proportional pressure regulator filling and venting the muscle through
//    a flow-limited (ISO 6358) path, the muscle's Tondu-Lopez force map with its volume changing with
//    contraction, a Dahl friction in the braid (the hysteresis), a payload with gravity, a load spring,
//    viscous and Coulomb friction, and end stops;
//  - "reference": the paper's Bouc-Wen structure in continuous time (a known structure for identification
//    tests), with a switchable continuous-time counterpart of each catalogue effect on top.
// The command is held over each sample and the ODE is integrated by Boost.Odeint's fixed-step RK4 at
// substeps per sample; docs/PHYSICS.md gives the equations, every parameter with its source, and the
// sample timing convention. Configuration allocates and throws; reset/step/measure do neither.
#pragma once

#include <array>
#include <cstdint>
#include <random>
#include <string>

#include <nlohmann/json.hpp>

namespace pamc::physics {

enum class Mode { Rig, Reference };

// The continuous-time counterparts of the catalogue effects (src/model/effects/<name>.cpp): the same
// names, parameters and units (y-unit = mm, u-unit = V), off by default. Rig mode accepts only the ones
// its physics does not already contain: delay, dead_band, creep, warm_up.
struct Effects {
  struct PressureLag {
    bool enabled = false;
    double tau = 0.05, slew = 1000.0;
  } pressure_lag;  // s, V/s
  struct Asymmetry {
    bool enabled = false;
    double gain = 1.0, w_up = 1.0, w_down = 0.3;
  } asymmetry;  // mm/V, V, V
  struct Creep {
    bool enabled = false;
    double fraction = 0.05, tau = 5.0;
  } creep;  // -, s
  struct MassSpring {
    bool enabled = false;
    double fn = 10.0, zeta = 0.5;
  } mass_spring;  // Hz, -
  struct ForceLoop {
    bool enabled = false;
    double fn = 10.0, zeta = 0.5, zmax = 0.5, delta = 0.5;  // Hz, -, mm, mm
  } force_loop;
  struct FrictionHysteresis {
    bool enabled = false;
    double zmax = 0.5, delta = 0.5;
  } friction_hysteresis;  // mm, mm
  struct Delay {
    bool enabled = false;
    double d = 0.01;
  } delay;  // s
  struct DeadBand {
    bool enabled = false;
    double threshold = -5.0;
  } dead_band;  // V
  struct Load {
    bool enabled = false;
    double compliance = 0.05;
  } load;  // mm/N
  struct Saturation {
    bool enabled = false;
    double knee = 30.0, width = 10.0;
  } saturation;  // mm, mm
  struct WarmUp {
    bool enabled = false;
    double tau = 60.0, gain = 0.1, shift = 0.0;
  } warm_up;  // s, -, mm
};

// Proportional pressure regulator (Festo VPPM-6L-L) and the path to the muscle.
struct Regulator {
  double setpoint_offset_V = 5.0;          // regulator setpoint voltage = offset + u
  double setpoint_bar_per_V = 0.8;         // 10 V -> 8 bar (gauge)
  double supply_bar = 9.0;                 // supply pressure (gauge)
  double atmosphere_bar = 1.01325;         // ambient (absolute)
  double conductance_dm3_per_s_bar = 0.8;  // ISO 6358 sonic conductance C of valve + tube
  double critical_ratio = 0.3;             // ISO 6358 critical pressure ratio b
  double laminar_ratio = 0.995;            // above this pressure ratio the flow is linear in the difference
  double band_bar = 0.3;                   // pressure error that opens the valve fully
  double tau_s = 0.003;                    // time constant of the valve opening
  double polytropic_index = 1.2;           // of the air in the muscle
  double temperature_K = 293.15;
  double dead_volume_cm3 = 15.0;  // tube and fittings
};

// Festo DMSP-20-200N fluidic muscle: Tondu-Lopez force map, rubber stiffness, braid friction.
struct Muscle {
  double diameter_mm = 20.0;
  double length_mm = 200.0;
  double braid_angle_deg = 25.29;      // initial braid angle theta0
  double tondu_k = 1.0;                // Tondu-Lopez end-effect factor
  double rubber_N_per_mm = 7.84;       // elastic force of the rubber against contraction
  double hysteresis_N = 5.0;           // braid friction (Dahl) level at 0 bar
  double hysteresis_N_per_bar = 10.0;  // ... its growth with the pressure
  double hysteresis_travel_mm = 0.3;   // Dahl pre-sliding travel
};

// Payload on the muscle.
struct Payload {
  double mass_kg = 16.0;
  double gravity_m_per_s2 = 9.81;
  double spring_preload_N = 300.0;  // load spring force at 0 mm contraction
  double spring_N_per_mm = 1.0;
  double viscous_N_s_per_m = 400.0;
  double coulomb_N = 5.0;
  double coulomb_velocity_mm_per_s = 1.0;  // width of the smooth (tanh) Coulomb law
};

// The reference mode's Bouc-Wen structure: Y = k rho v + b + k (1 - rho) h.
struct Reference {
  double k = 9.0;             // mm/V
  double rho = 1.25;          // -
  double b = 18.0;            // mm
  double alpha = 1.0;         // -
  double beta = 0.35;         // 1/V
  double gamma = 0.25;        // 1/V
  double tau_valve_s = 2e-5;  // fast valve stage: v follows the held command
};

struct PhysicsConfig {
  double Ts = 1e-3;                  // sample time [s]
  int substeps = 20;                 // fixed RK4 steps per sample in mode rig
  int reference_substeps = 200;      // ... in mode reference (short against tau_valve_s)
  double u_min = -5.0, u_max = 5.0;  // valve command range [V]; regulator setpoint voltage = 5 V + u
  Mode mode = Mode::Rig;
  bool stroke_limits = true;  // end stops
  double stroke_min_mm = 0.0;
  double stroke_max_mm = 40.0;
  double noise_std_mm = 0.004;  // sensor noise std (0: none)
  double quantum_mm = 0.001;    // sensor quantum (0: none)
  std::uint64_t seed = 1;
  Regulator regulator;
  Muscle muscle;
  Payload payload;
  Reference reference;
  Effects effects;

  static PhysicsConfig defaults();
  // Defaults overridden by j; throws std::invalid_argument("<where>: ...") naming the bad key.
  static PhysicsConfig fromJson(const nlohmann::json& j, const std::string& where);
  nlohmann::json toJson() const;
  // RK4 steps per sample in the configured mode.
  int activeSubsteps() const noexcept { return mode == Mode::Rig ? substeps : reference_substeps; }
};

// States of both modes share one fixed-size array (docs/PHYSICS.md lists them).
constexpr int kPhysicsStates = 10;
using PhysicsState = std::array<double, kPhysicsStates>;
constexpr int kDelayRing = 1024;  // command history [samples]; delay d <= (kDelayRing - 2) Ts

class PhysicsPlant {
 public:
  explicit PhysicsPlant(const PhysicsConfig& c = PhysicsConfig::defaults());
  const PhysicsConfig& config() const { return cfg_; }

  // At rest (steady state) under the constant command u0 [V] and external force [N].
  void reset(double u0_V, double force_N = 0.0) noexcept;
  // Holds u over one sample [t, t + Ts), integrates, returns the true position at the end [mm].
  double step(double u_V, double force_N = 0.0) noexcept;
  // The sensor now: true position + N(0, noise_std_mm), quantised to quantum_mm [mm].
  double measure() noexcept;
  double position() const noexcept { return y_; }
  // Muscle pressure (gauge) [bar]; in mode reference the regulator's setpoint for the effective command.
  double pressure_bar() const noexcept;
  // The ODE state (for tests and logs).
  const PhysicsState& state() const noexcept { return x_; }

 private:
  void integrate(double cmd_first, double cmd_second, double t_switch, double force_N) noexcept;
  double output() const noexcept;
  double deadBand(double u) const noexcept;

  PhysicsConfig cfg_;
  PhysicsState x_{};
  double y_ = 0.0;
  double u_last_ = 0.0;  // last valid command (a non-finite one holds it)
  double force_last_ = 0.0;
  double t_ = 0.0;        // since reset [s] (warm_up)
  double y_start_ = 0.0;  // warm_up's stage input at reset
  std::array<double, kDelayRing> ring_{};
  int head_ = 0;
  int delay_whole_ = 0;      // whole samples of the delay
  double delay_frac_ = 0.0;  // fraction of a sample
  std::mt19937_64 rng_;
  std::normal_distribution<double> noise_{0.0, 1.0};
};

}  // namespace pamc::physics
