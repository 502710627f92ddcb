// Position controllers of the paper: open loop (inverse static characteristic), PI (eq. 16),
// PI + active model compensation (eqs. 14-19) and PID + extended state observer (eqs. 22-25); and the
// feed-through of an identification input (Kind::Input).
//
// Lifecycle: construction (makeController) may allocate and throw on a bad configuration; activate()
// resets state; update() runs once per cycle, is noexcept, allocation-free and returns the valve
// command with its parts.
//
// Units and the interpretation of the paper's gains (written down once, here):
//  - position in mm, command u in V relative to the valve's mid-range (valve voltage = 5 V + u,
//    so the real 0-10 V range is u in [-5, 5] V);
//  - all gains are continuous-time, as the ESO's observer gains of eq. (24) are: kp [V/mm],
//    ki [V/(mm s)] multiplying the integral of the error, taken as the sum of e_i * Ts. Read
//    literally (ki times the bare sum at 1 kHz, i.e. 150 V/(mm s)) the integral would close the
//    loop at hundreds of rad/s, unstable on any pneumatic plant; read as printed in continuous time
//    (0.15) the ramps lag ten times the paper's errors. The default ki is inferred from the paper's
//    own results (docs/CALIBRATION.md); --ki 0.15 is the printed value;
//  - kc [V/mm] multiplies the predicted error of eq. (18).
//
// The default gains are kDefaultGains, written once: ControllerConfig's defaults, the command line's
// (--kp, --ki, --kc show them), the fault tools', the experiments' and the EDS defaults of 0x2000:01-03
// (a test holds od/controller.eds to them) all read it.
#pragma once

#include <array>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "control/actuation.hpp"
#include "estimation/active_model.hpp"
#include "model/held_rest.hpp"
#include "model/model.hpp"

namespace pamc::control {

// Input: no controller - the "setpoint" is the valve command itself (an identification input, `--input`),
// passed through within [u_min, u_max]; the measured position is not used. Mbc: model-based control (not
// in the paper; docs/CONTROL.md) - the model's inverse through the commands in flight as a feedforward,
// the nominal PI on top.
enum class Kind { OpenLoop = 0, PI = 1, PidEso = 2, PiAmc = 3, Input = 4, Mbc = 5 };
const char* toString(Kind k);
// Whether the kind runs the model (the open loop's inverse, the AMC's and MBC's estimator and prediction).
constexpr bool usesModel(Kind k) noexcept { return k == Kind::OpenLoop || k == Kind::PiAmc || k == Kind::Mbc; }
Kind kindFromString(const std::string& s);  // "open", "pi", "eso", "amc", "input", "mbc" (throws)

// The PI and AMC gains every tool runs unless told otherwise: kp and kc as the paper prints them, ki the
// reading of the printed 0.15 that `pamc calibrate` chose on the physics plant (docs/CALIBRATION.md).
struct Gains {
  double kp;  // [V/mm]
  double ki;  // [V/(mm s)]
  double kc;  // [V/mm]
};
inline constexpr Gains kDefaultGains{0.1, 3.0, 0.06};

// The model-based controller's settings (Kind::Mbc, src/control/mbc.cpp).
struct MbcSettings {
  // The horizon in samples its inverse reaches the setpoint at (0: automatic - the bus delay plus the
  // time the model takes to make 10 % of its response to a command step, at least one sample after the
  // commands in flight).
  int horizon = 0;
  // Time constant [s] of the filter on the UKF's modelling-error estimate that the feedforward aims off
  // by. Chosen from 0.5, 2, 10 and 1000 s on Table 2's triangle along a diagnose ladder (docs/CONTROL.md,
  // "Model-based control"): faster filters track better with the final model but worse with a middle rung.
  double error_tau_s = 10.0;
  // The setpoint governor. The inverse and the PI follow the setpoint ahead through a follower limited to
  // a rate [mm/s] and an acceleration [mm/s^2], braking so as to arrive without overshoot; a setpoint
  // slope below the rate passes (Table 2's fastest is 9.4 mm/s). Without it a step is taken by a short-
  // horizon inverse that overshoots a payload still moving (docs/CONTROL.md).
  // The limits are the fixed ones below, lowered to this share of the model's own pace where that is
  // slower (modelPace: its fastest speed and acceleration under a step across its input range): a quarter
  // of the command's span to drive the speed, a quarter to change it, the rest left to the setpoint's level
  // and the loop. The pace only lowers them: a model's step response is an extrapolation where its record
  // held no steps, and one too fast overshot a square wave by 44 % (docs/CONTROL.md). 0: the fixed limits.
  double pace_share = 0.25;
  // The fixed limits: the most the governor asks of any muscle. rate_mm_s 0: no governor, the setpoint as it
  // is. Chosen on the square wave of two plants (docs/CONTROL.md).
  double rate_mm_s = 60.0;
  double accel_mm_s2 = 600.0;
  // The acceleration while the model carries the loop - its feedforward on, and the PI's integral, the part of
  // the command it did not predict, within carried_share of the command's span over the last carried_tau_s
  // seconds (a peak that decays) - within the same share of the model's pace. A model that carries the loop
  // is followed at its own pace; one the PI has to correct is not asked to brake a payload it mispredicts
  // (docs/CONTROL.md, "The governor and the model's pace"). At most accel_mm_s2 - the same - turns it off.
  double accel_carried_mm_s2 = 1800.0;
  double carried_share = 0.01;
  double carried_tau_s = 10.0;
};

// The PID + ESO's observer: the plant it assumes (docs/CONTROL.md). order 2 (default): the paper's,
// eqs. (22)-(24), a double integrator x1'' = b0 u + tau, with fal() of delta in mm and b0 [mm/(s^2 V)]
// (the paper: beta1 = beta2 = beta3 = 100, delta = 500, b0 = 1). 1: pamc's own first-order observer, the
// same extended-state idea on a first-order lag (what a valve filling a muscle is from command to
// position): x1' = (gain u - x1) / tau + x2, the total disturbance x2 estimated with both eigenvalues of
// the error dynamics at -wo, u = u_n - x2 tau / gain.
struct EsoSettings {
  int order = 2;
  double beta1 = 100.0, beta2 = 100.0, beta3 = 100.0, delta = 500.0, b0 = 1.0;
  double gain = 8.4;  // [mm/V]
  double tau = 0.3;   // [s]
  double wo = 0.5;    // [rad/s]
};

struct ControllerConfig {
  double Ts = 1e-3;
  double u_min = kCommandMin, u_max = kCommandMax;  // valve command range [V]
  double kp = kDefaultGains.kp;                     // [V/mm]
  double ki = kDefaultGains.ki;                     // [V/(mm s)]; the printed value is 0.15
  double kc = kDefaultGains.kc;                     // [V/mm]
  // AMC prediction horizon in samples: 1 is eq. (17); longer horizons roll the model out so that
  // its lags and delays shape the compensation (see docs/CONTROL.md). 0: automatic - 1 with
  // amc_inverse = 0, otherwise the bus delay plus the time the model takes to make 10 % of its response
  // to a command step (modelResponseSamples): the correction then amplifies sensor noise at most about
  // ten times more than a static inverse would.
  int amc_horizon = 1;
  // 0 uses u_c = kc e_hat (the paper's form, eq. 18). > 0 is the predictive form: the model is rolled
  // out over the horizon from the UKF's posterior, the commands still in flight on the bus first and
  // then the nominal command held; u_c = amc_inverse * e_hat / g cancels that fraction of the predicted
  // error, g the model's response at the horizon to a change of the command. The compensation then
  // rests on how well the model knows the plant's dynamics.
  double amc_inverse = 0.0;
  MbcSettings mbc;
  // Eq. (17) read as printed (true: Y_{k+1} = H(h_{k+1}, u_n(k)), the compensation feeding back on
  // itself through the direct feedthrough with gain kc k rho) or as an increment on the posterior
  // output (false); see docs/CONTROL.md. Only for the paper's form (amc_inverse = 0, horizon 1).
  bool amc_as_printed = true;
  // Eq. (17) bus-aware (the paper's form, amc_inverse = 0): Y_hat is predicted from the posterior rolled
  // through the commands still on the bus (delay_cycles of them) and then one step of the nominal
  // command - a Smith predictor of the paper's prediction, at the horizon delay_cycles + 1, where the
  // setpoint is read too. The compensation then no longer feeds back on itself through the delay
  // (docs/EXPERIMENTS.md, "The paper's AMC, bus-aware").
  bool amc_bus_aware = false;
  EsoSettings eso;
  // Cycles between issuing a command and the first measurement that reflects it, beyond the one
  // sample of any sampled loop (actuation.hpp).
  int delay_cycles = kBusDelayCycles;
  // Open loop: false inverts the identified model's static characteristic (the centre line of its
  // loop); true inverts the straight line fitted to that characteristic - a feedforward that knows the
  // muscle's range but neither its curvature nor its hysteresis.
  bool open_loop_linear = false;
  model::Model model;  // identified reference model (open loop, AMC)
  estimation::ActiveModelSettings ukf;
};

struct ControlOutput {
  double u = 0.0;      // saturated command sent to the valve [V]
  double u_n = 0.0;    // nominal controller part [V]
  double u_c = 0.0;    // compensation part (AMC u_c, or the ESO's disturbance estimate in volts) [V]
  double y_hat = 0.0;  // estimator output (AMC posterior / ESO x1_hat) [mm]
  bool saturated = false;
  bool estimator_reset = false;  // the estimator started over this cycle (the UKF or the ESO)
  // The measured position was not used this cycle: not finite (every feedback controller), or an
  // outlier for the AMC's UKF (ActiveModelSettings::gate_nis). The PI then works with the last usable
  // position and its integral is held; the estimators run on their models.
  bool measurement_rejected = false;
  // The MBC's response monitor (detail::ResponseMonitor): its feedforward is off because its model does not
  // move as the muscle does, by this ratio of the muscle's motion to the model's (NaN for the others).
  bool model_distrusted = false;
  double model_ratio = NAN;
  // The MBC's setpoint governor's acceleration this cycle [mm/s^2]: the faster one while its model carries the
  // loop (MbcSettings::accel_carried_mm_s2; NaN for the others).
  double governor_accel = NAN;
};

class Controller {
 public:
  virtual ~Controller() = default;
  virtual Kind kind() const = 0;
  // How many samples ahead `yd_next` of update() should be (the AMC's prediction horizon).
  virtual int lookahead() const { return 1; }
  // Rest at command u0 with measured position y0.
  virtual void activate(double u0, double y0) noexcept = 0;
  // One cycle: setpoint now and lookahead() cycles ahead, measured position (and load if measured).
  virtual ControlOutput update(double yd, double yd_next, double y, double load = 0.0) noexcept = 0;
  // The loop sent u_applied instead of this cycle's command (its slew limit after a restart): the
  // estimators' command history holds what went out, and the integral does not wind up against the
  // limit (conditional integration, as at saturation).
  virtual void limited(double u_applied) noexcept { (void)u_applied; }

  // Read-only views for tests and diagnostics (not needed by the cycle).
  // The PI integral [V] (0 for the open loop).
  virtual double integral() const noexcept { return 0.0; }
  // The AMC's estimator (nullptr for the other controllers).
  virtual const estimation::ActiveModel* activeModel() const noexcept { return nullptr; }
  // The ESO's total-disturbance estimate (x3_hat [mm/s^2] of eq. (24), x2_hat [mm/s] of the
  // first-order form; 0 for the other controllers).
  virtual double disturbance() const noexcept { return 0.0; }
};

// Samples until the model's output has made `fraction` of its response to a small command step from
// mid-range (1 for the plain Bouc-Wen model, which responds at once; about 0.1 tau/Ts for 10 % with a
// pressure lag of time constant tau).
int modelResponseSamples(const model::Model& m, double Ts, double u_min, double u_max, double fraction);
// The sign of the model's response to that step once it has settled: +1 where a larger command gives a larger
// output (the core's k alone does not say: a fitted k may be negative with rho, k rho > 0).
double modelGainSign(const model::Model& m, double Ts, double u_min, double u_max);

// The model's pace: the fastest speed [output units/s] and acceleration [output units/s^2] of its output
// under a step across [u_lo, u_hi], up and then down, the slower direction's (each over 10 ms spans, at
// 1 kHz whatever the loop's rate); 0 and 0 for a model that makes 90 % of the step within 5 ms (no
// dynamics of its own: the Bouc-Wen core and static effects answer at once) or whose output is not finite.
struct ModelPace {
  double speed = 0.0, accel = 0.0;
};
ModelPace modelPace(const model::Model& m, double u_lo, double u_hi);

// The MBC's setpoint governor in effect: rate 0 (off) where mbc.rate_mm_s is 0 or the model does not come to
// rest (mbcModelRest); else the fixed rate and
// acceleration, each lowered to pace_share of the model's pace over its feedforward's range where that is
// below it (from_model: one of them was).
struct GovernorLimits {
  double rate_mm_s = 0.0, accel_mm_s2 = 1.0;
  double accel_carried_mm_s2 = 1.0;  // while the model carries the loop (MbcSettings), at least accel_mm_s2
  bool from_model = false;
  ModelPace pace;  // the model's (0 and 0 where it has none or pace_share is 0)
};
GovernorLimits mbcGovernor(const ControllerConfig& c);
// The MBC's feedforward range: the valve's command range within the input range the model was
// identified on (model.json's `range`; the valve's alone for a model without one).
model::Interval mbcCommandRange(const ControllerConfig& c);
// Whether the MBC's model comes to rest under a held command over that range at the loop's period
// (model::heldRest). Where it does not, the MBC is its nominal PI alone, on the setpoint itself: an inverse of
// a model that swings under a held command swings the valve (docs/CONTROL.md, "A model that does not come to
// rest").
model::HeldRest mbcModelRest(const ControllerConfig& c);

// The automatic horizon of the predictive forms (AMC and MBC): the bus delay plus the samples the model
// takes to make 10 % of its response to a command step, and at least one more than the bus delay.
int responseHorizon(const ControllerConfig& c);
// The AMC horizon in effect for a configuration (resolves amc_horizon = 0).
int amcHorizon(const ControllerConfig& c);
// The MBC horizon in effect (resolves mbc_horizon = 0).
int mbcHorizon(const ControllerConfig& c);

// Throws std::invalid_argument on a bad configuration.
std::unique_ptr<Controller> makeController(Kind kind, const ControllerConfig& cfg);
std::unique_ptr<Controller> makeMbc(const ControllerConfig& cfg);  // Kind::Mbc (mbc.cpp)
// The checks makeController makes before it builds anything (throws std::invalid_argument): cheap, so a
// caller can refuse a configuration at once and build it elsewhere.
void validate(const ControllerConfig& cfg);

// Inverse of a model's static characteristic: the centre line between the ascending and
// descending branches of a slow full-range sweep, made monotonic and inverted by table.
class InverseStatic {
 public:
  void build(const model::Model& m, double u_min, double u_max, double Ts);
  double operator()(double y) const noexcept;
  double forward(double u) const noexcept;
  // The characteristic's slope dy/du at the output y (its nearest end's beyond it); 0 before build().
  double slope(double y) const noexcept;

 private:
  std::vector<double> u_, y_;  // y_ increasing with u_
};

}  // namespace pamc::control
