// A physical effect: one self-contained extension of the reference model.
//
// An effect is a small block in the model's signal chain
//
//   command u --[input effects]--> u_eff --[Bouc-Wen core]--> y_core --[output effects]--> y
//
// Input effects act on the command before the hysteresis (valve, pressure, delays);
// output effects act on the displacement after it (payload, stroke limits, creep).
// Each effect owns its parameters (with bounds), its few states and one step function.
// The same effect code runs in the identification, the estimator, the compensator's
// prediction and the plant emulator.
#pragma once

#include <memory>
#include <string>
#include <vector>

namespace pamc::model {

enum class Stage { Input, Output };

// Units say how identification bounds follow the data (ident::dataBounds):
//  "s" time (clamped to the sample time and record length), "Hz" frequency, "y-unit" a size in
//  output units (scaled with the output's range), "y-level" an output level (within its range),
//  "y-stop" an end stop (at an extreme the record rests on, else a range beyond the data: none),
//  "u-unit" a size in input units, "u-level" an input level, "u-unit/s" an input rate,
//  "y-unit/load-unit" a compliance, "1/y-unit" and "1/y-unit^2" a curve's slope and curvature per output
//  unit, "-" dimensionless (bounds as given).
struct ParamSpec {
  std::string name;
  double lo;   // identification bound (for a 40 mm / 10 V / 1 kHz rig; scaled to the data)
  double hi;   // identification bound
  double def;  // default value
  std::string unit;
};

// Per-sample signals besides the command that some effects need.
struct StepContext {
  double Ts = 1e-3;    // sample time [s]
  double load = 0.0;   // measured external load (file units, e.g. N) - 0 when absent
  double u_eff = 0.0;  // effective command of this sample (set by the model for output effects)
};

constexpr int kMaxEffectStates = 260;  // per effect; storage is fixed so a step never allocates

class Effect {
 public:
  virtual ~Effect() = default;
  virtual const char* name() const = 0;
  // One line: the physics this effect stands for.
  virtual const char* explanation() const = 0;
  virtual Stage stage() const = 0;
  // Order within its stage (lower runs first), so effects compose the same way whatever
  // order a user lists them in.
  virtual int rank() const = 0;
  virtual const std::vector<ParamSpec>& params() const = 0;
  virtual int numStates() const = 0;
  // How many of the leading states the estimator carries in its own joint state (with their
  // uncertainty) instead of propagating them with its mean: the states through which the input of an
  // output effect reaches the displacement with a lag (inertia, creep), so that the measurement at one
  // sample hardly depends on the hysteresis state of that sample. 0 for effects with a direct path.
  virtual int numFilterStates() const { return 0; }
  // Put the states at rest for a constant stage input `in0`.
  virtual void init(const double* p, double* s, double in0, const StepContext& c) const noexcept = 0;
  // One sample: takes the stage input at sample k, returns the stage output at sample k and
  // advances the states to k+1. Must not allocate or throw.
  virtual double step(const double* p, double* s, double in, const StepContext& c) const noexcept = 0;
  // An effect that stands for the same physics in another form (nullptr if none): a model holds
  // at most one of the two (Model::addEffect refuses the second).
  virtual const char* alternativeTo() const { return nullptr; }
  // The effects this one holds as special cases when it is a richer form of them (hysteretic_spring:
  // mass_spring at zmax 0, force_loop at hardening 0); empty for the catalogue's own effects. Such an
  // effect is no candidate of diagnose's own unless named (--candidates): it is tried in their place once
  // the ladder ends above the noise with one of them (Diagnosis::refinements). A model holds at most one
  // of them and it (Model::addEffect).
  virtual std::vector<std::string> refines() const { return {}; }
  // Effects of the chain whose physics this richer form holds as well (muscle_balance's force-length map:
  // saturation's stiffening towards the end of the stroke). A refinement into it drops them.
  virtual std::vector<std::string> absorbs() const { return {}; }
  // How far the core's static displacement may reach beyond the output's span, as a multiple of the
  // search's usual box: a balance whose force-length map holds a muscle's stiffening (muscle_balance)
  // turns a larger static displacement into the stroke - on the physics plant 4.5x the output's slope
  // per volt, past the box of 4x that fits every other chain.
  virtual double coreReach() const { return 1.0; }
  // A direction of the parameters that the forms it refines leave unidentified and along which the static
  // map stays (pneumatic_balance: the pressure's force s times larger, the balance's weight moved to keep
  // the map - muscle_balance's map cannot tell s apart, the pressure's dynamics can). Rewrites p for a stage
  // input scaled by s (the core's gain and offset go with it), given the stage input's range [lo, hi] on the
  // record; false when the effect has no such direction or it is not defined at p. Diagnose's refinement
  // searches the richer form from points along it (Diagnosis::searchAlong).
  virtual bool scaleAlong(double /*s*/, double /*lo*/, double /*hi*/, double* /*p*/) const { return false; }
  // A static map the effect's parameters can put its rest on: rewrites p so that the stage inputs xs rest
  // at the outputs ys (a balance's force-length map seeded from the saturation it absorbs); false when the
  // effect has no such map or ys does not determine it. Diagnose's refinement starts the richer form there.
  virtual bool seedRest(const std::vector<double>& /*xs*/, const std::vector<double>& /*ys*/, double* /*p*/) const {
    return false;
  }
  // Parameters the output alone holds weakly - a fit's end lies anywhere along them, and where it lies
  // decides its basin (pneumatic_balance: the gas's law, the atmosphere and the supply in the balance's
  // units, the flow's critical ratio, the polytropic index). Each has a unit its box scales by a factor
  // (dataBounds). Diagnose polishes the final model once more from them at their catalogue defaults
  // (Diagnosis::polish), and so a refinement to the effect that does not gain (Diagnosis::restartWeak).
  virtual std::vector<std::string> weaklyHeld() const { return {}; }
  // Whether the effect reads StepContext::load (the data must then carry a load column).
  virtual bool needsLoad() const { return false; }
  // Whether the effect has a direction-dependent version ("<name>_updown": separate parameters for a
  // rising and a falling stage input; directional.cpp). Such an effect implements retune.
  virtual bool directional() const { return false; }
  // Whether the effect's first state is a level that moves towards its stage input (a lag, a flow through
  // a valve). Its direction-dependent version then picks the parameter set by the sign of the input minus
  // that level - filling or venting, the way a valve switches - rather than by the direction the input
  // last moved in: a command that turns before the pressure has caught up does not turn the flow.
  virtual bool followsInput() const { return false; }
  // Recomputes what init derived from the parameters (cached filter gains) for new parameters, keeping
  // the dynamic states: the direction-dependent version switches parameter sets mid-run.
  virtual void retune(const double* /*p*/, double* /*s*/, const StepContext& /*c*/) const noexcept {}
};

using EffectFactory = std::unique_ptr<Effect> (*)();

// "<name>_updown": the direction-dependent version of a directional() effect (directional.cpp).
inline constexpr const char* kDirectionalSuffix = "_updown";
// "pressure_lag" for "pressure_lag_updown"; empty for a name that is no direction-dependent version.
inline std::string directionalBase(const std::string& name) {
  const std::string suffix = kDirectionalSuffix;
  const bool updown =
      name.size() > suffix.size() && name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
  return updown ? name.substr(0, name.size() - suffix.size()) : std::string();
}
// Throws std::invalid_argument when `inner` has no such version.
std::unique_ptr<Effect> makeDirectional(std::unique_ptr<Effect> inner);

struct CatalogueEntry {
  const char* name;
  EffectFactory make;
};

// All registered effects (src/model/effects/catalogue.inc lists them, one line each).
const std::vector<CatalogueEntry>& catalogue();
// Throws std::invalid_argument listing the known names when `name` is unknown.
std::unique_ptr<Effect> makeEffect(const std::string& name);
std::string knownEffectNames();

}  // namespace pamc::model
