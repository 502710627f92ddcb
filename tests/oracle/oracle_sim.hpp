// The test oracle: a second, independent continuous-time simulator of a pneumatic artificial muscle,
// written for the tests only. It shares no code with src/ (neither the model nor the plant emulator):
// its own equations (continuous-time ODEs of the Bouc-Wen core and of each physical effect), its own
// adaptive Dormand-Prince RK5(4) integrator, its own excitations and its own CSV writer. It produces
// measurement records (CSV t,u,y[,load]; s, V, mm) on which `pamc fit`, `pamc compare` and
// `pamc diagnose` are tested with data that no model code made.
//
// Signal chain (in continuous time, t in seconds):
//
//   u(t) held over each sample [k Ts, (k+1) Ts)
//     -> delay        u_d(t) = u(t - d)                        (exact: the switching instants move by d)
//     -> valve stage  v' = (u_d - v) / tau_v                   (always on; tau_v = 1e-6 s by default)
//     -> dead_band    w = max(v, threshold)
//     -> pressure_lag p' = clamp((w - p) / tau, -slew, slew)   s = p (or s = w without it)
//     -> core         h' = alpha s' - beta s' |h| - gamma |s'| h,   Y = k rho s + b + k (1 - rho) h
//     -> asymmetry    z' = s' (1 - z / w_up) for s' > 0, s' (1 + z / w_down) for s' < 0;  y += gain z
//     -> load         y -= compliance L   (L: the load column through the same fast first-order stage)
//     -> saturation   above the knee y = knee + width tanh((y - knee) / width)
//     -> creep        c' = (fraction y - c) / tau;  y += c
//     -> friction_hysteresis  z' = a g y' / (1 + a g), a = zmax / delta, g = 1 - sgn(y') z / zmax;  y -= z
//     -> mass_spring  x'' = wn^2 (y - x) - 2 zeta wn x';  y = x
//        or force_loop x'' = wn^2 (y - x - z) - 2 zeta wn x',  z' = (zmax / delta)(1 - sgn(x') z / zmax) x'
//        or muscle_balance x'' = wn^2 ((y + w) exp(-x / L) - w - x - F_f) - 2 zeta wn x', F_f elastoplastic
//                    Maxwell-slip elements with levels f0 + fp max(y + w, 0), inelastic stops lo, hi
//        or pneumatic_balance: muscle_balance with y replaced by the muscle's pressure p, which a regulator
//                    opened by (y - p) / band fills from the supply and vents to the atmosphere through
//                    isentropic nozzles (choked below 0.528), polytropic air in V(x) = V0 (1 + swell L (1 - exp(-x / L)))
//     -> warm_up      y += (1 - exp(-t / tau)) (gain (y - y(0)) + shift)
//
// The sample y_k is the output at the end of the sample in which u_k was held ((k+1) Ts: open-loop DAQ
// timing, y_k responds to u_k), plus Gaussian noise and quantisation. Everything starts at rest at
// u_0 with h = 0.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace pamc::oracle {

struct Core {
  double k = 6.5;      // [mm/V]
  double rho = 1.15;   // [-]
  double b = 20.0;     // [mm]
  double alpha = 1.0;  // [-]
  double beta = 0.5;   // [1/V]
  double gamma = 0.2;  // [1/V]
};

// One parameter of an effect: name, bounds (those of pamc's catalogue, for a 40 mm / 10 V / 1 kHz rig)
// and default.
struct ParamInfo {
  std::string name;
  double lo, hi, def;
};
struct EffectInfo {
  std::string name;
  std::vector<ParamInfo> params;
  bool needs_load = false;
  std::string meaning;
};
// The effects the oracle knows, named and parameterised as pamc's catalogue.
const std::vector<EffectInfo>& effectTable();
const EffectInfo& effectInfo(const std::string& name);  // throws std::invalid_argument

// An effect switched on with its parameters (missing ones take their defaults).
struct EffectSpec {
  std::string name;
  std::map<std::string, double> params;
};
// "name" or "name:param=v,param=v"; throws std::invalid_argument.
EffectSpec parseEffect(const std::string& text);
// "k=6.5,rho=1.15,..." over the given core; throws std::invalid_argument.
Core parseCore(const std::string& text, Core base = {});
// Checks names, parameters, bounds and combinations (one of mass_spring, force_loop, muscle_balance,
// pneumatic_balance); throws
// std::invalid_argument.
void validateEffects(const std::vector<EffectSpec>& effects);

// pneumatic_balance's air (README, "The physics"), in the balance's units: pressures in y-units (mm), the
// gauge pressure's force p + w, so the absolute pressure is P = p + w + span; volumes over V0.
//   opening  o = clamp((y - p) / band, -1, 1)                        y: the setpoint (the chain's output so far)
//   nozzle   psi(r) = sqrt(2 k / (k - 1) (r^(2/k) - r^((k+1)/k))), k = 1.4, psi(r_c) below r_c = 0.528 (choked)
//   flow     q = rate o Q(P_s, P) / (P_s psi(r_c))                    o > 0: from the supply, P_s = supply + span
//            q = vent rate o Q(P, P_a) / (P_s psi(r_c))               o < 0: to the atmosphere, P_a = span
//            Q(P_u, P_d) = P_u psi(P_d / P_u) (reversed when P_d > P_u): mass flow R T mdot / V0 [y-unit/s]
//   volume   v(x) = V / V0 = 1 + swell L (1 - exp(-x / L))            (dV/dx ~ exp(-x / L): virtual work of the map)
//   air      p' = P' = (n / v) (q - P v'(x) x')                       polytropic
struct PneumaticAir {
  double rate = 1000, vent = 1, band = 1, span = 14, supply = 100, swell = 0, n = 1.3, w = 0, L = 1e4;
  static double psi(double r);                                // the nozzle's flow function (r in [0, 1])
  double opening(double y, double p) const;                   // o
  double volume(double x) const;                              // v(x)
  double flow(double p, double o) const;                      // q [y-unit/s]
  double pressureRate(double y, double p, double x, double xd) const;  // p' [y-unit/s]
};
// The air of a pneumatic_balance spec (missing parameters at their defaults); throws std::invalid_argument.
PneumaticAir pneumaticAir(const EffectSpec& e);

struct SimOptions {
  double Ts = 1e-3;         // sample time [s]
  double valve_tau = 1e-6;  // time constant of the valve stage (and of the load signal) [s]
  double rtol = 1e-11;      // integrator tolerances (relative, absolute in the state's units)
  double atol = 1e-11;
  double max_step = 1e-3;    // largest integrator step [s]
  double noise_std = 0.005;  // Gaussian measurement noise [mm]
  double quantum = 0.001;    // quantisation of the measurement [mm] (0: none)
  std::uint64_t noise_seed = 1;
};

struct Record {
  double Ts = 1e-3;
  std::vector<double> t, u, y, y_clean, load;  // load empty when there is no load column
  double noise_std = 0.0, quantum = 0.0;
  long steps = 0, rejected = 0;  // integrator statistics
  // The std of the measurement error including quantisation: sqrt(std^2 + q^2 / 12).
  double noise() const;
};

// The chain stepped one sample at a time, as the plant of a closed loop, where a sample's command is known
// only when the sample starts. simulate() steps it over a whole command, so a stepped run is the batch run
// sample for sample.
class Stepper {
 public:
  // Throws std::invalid_argument on bad effects or options.
  Stepper(const Core& core, const std::vector<EffectSpec>& effects, const SimOptions& opt);
  ~Stepper();
  Stepper(const Stepper&) = delete;
  Stepper& operator=(const Stepper&) = delete;

  // At rest under the command u0 and the load, t = 0, the noise restarted from its seed.
  void reset(double u0, double load = 0.0);
  // Holds u and the load over the next sample; returns the measurement at its end (noise, quantisation).
  // Throws std::invalid_argument on a non-finite command.
  double step(double u, double load = 0.0);
  double clean() const;    // the last sample's output without noise [mm]
  bool needsLoad() const;  // the effect load is on
  double pressure() const;  // pneumatic_balance's pressure p at the last sample's end (NaN without it)
  long steps() const;      // integrator statistics since the reset
  long rejected() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// Simulates the chain for the command u (one value per sample) and, when non-null and non-empty, the
// load column. Throws std::invalid_argument on bad effects or sizes.
Record simulate(const Core& core, const std::vector<EffectSpec>& effects, const std::vector<double>& u,
                const std::vector<double>* load, const SimOptions& opt);

// Excitations. SPEC: segments joined by '+', each KIND[:key=value,...]; a segment with dur=S lasts S
// seconds, the others share the rest of the duration equally. Kinds (lo/hi default -3/3 V):
//   steps:lo,hi,min=0.3,max=3     random levels held random durations (uniform in [min, max] s)
//   chirp:f0=0.05,f1=5,lo,hi      linear-frequency sweep around the middle of [lo, hi]
//   sine:f=0.1,lo,hi,phase=0      sine (phase in degrees, 0 starts at the middle going up)
//   triangle:f=0.05,lo,hi         triangle starting at lo
//   multisine:fmin=0.02,fmax=2,n=20,lo,hi   random-phase multisine scaled into [lo, hi]
//   hold:level=0                  constant
//   ramp:from=0,to=3              linear ramp over the segment
//   mixed:lo,hi                   steps (35 %), a hold (7.5 %), a chirp 0.05 -> 3 Hz (25 %), sines
//                                 of 0.1 and 0.3 Hz (12.5 % each), a hold (7.5 %); holds at random levels
// Throws std::invalid_argument with a one-line message on a bad spec.
std::vector<double> makeSignal(const std::string& spec, double duration, double Ts, std::uint64_t seed);

// The pre-decided test set (tests/oracle/cases.json).
struct RecordSpec {
  std::string input;
  std::string load;  // empty: no load column
  double duration = 30.0;
  std::uint64_t seed = 1;
};
struct Case {
  std::string name;
  std::string description;
  Core core;
  std::vector<EffectSpec> effects;
  double noise_std = 0.005;
  RecordSpec train, validate;
  std::vector<std::string> expected;
};
std::vector<Case> loadCases(const std::string& path);  // throws std::runtime_error naming the file
// The record `which` ("train" or "validate") of a case.
Record makeCaseRecord(const Case& c, const std::string& which, SimOptions opt = {});

// Writes t,u,y[,load] to PATH.tmp and renames it to PATH; throws std::runtime_error.
void writeRecordCsv(const std::string& path, const Record& r);

// Default path of cases.json (the source tree's).
std::string defaultCasesPath();

}  // namespace pamc::oracle
