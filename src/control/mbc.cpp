// Model-based control (Kind::Mbc; not in the paper, docs/CONTROL.md "Model-based control"):
//
//   u_k = u_ff + kp e_k + ki sum(e Ts),   e_k = r(k - H) - y_k (the nominal PI, eq. 16, on top)
//
// r is the setpoint H samples ahead through a governor of limited rate and acceleration (SetpointGovernor,
// controller_parts.hpp): a ramp passes, a step is taken at a pace the muscle can follow. The PI acts on the
// governed setpoint of now, r(k - H) (y_d(k) when the governor is off): on the setpoint of the step itself
// its integral filled while the plant was on its way, and the payload overshot (docs/CONTROL.md).
// u_ff is the model's inverse along r. A reference model - the model driven by the
// feedforward alone, started at rest with the loop - is rolled, as a Smith predictor rolls its model,
// through the feedforwards already sent and not yet in effect, then u_ff held; u_ff is the command for
// which it reaches r(k) - m_k at the horizon H (a few secant steps from the last solution; H the bus
// delay plus the time the model takes to make 10 % of its response, as the predictive AMC's). m_k is the
// modelling error the UKF estimates - its posterior output against the reference model's - low-passed
// (mbc_error_tau_s). Measurements reach the command only through m_k and the PI: an inverse re-solved
// from the posterior every cycle is an integral action of gain 1/(model gain) per sample, which tracked the
// physics plant's triangle 9-13x worse than the PI with the models of a diagnose ladder (docs/CONTROL.md).
//
// The feedforward is only used where the model was identified (model.json's `range`): a setpoint or a
// position outside its output range, and the nominal PI runs alone, its integral taking over the last
// feedforward (bumpless; taken back the same way on return). The inverse is solved within the model's
// input range: a feedforward beyond it is held at its edge (switched off there instead, the fill of a
// vented muscle left the edge's command in the integral and overshot by 27 mm). The PI starts at the
// command in effect, or - a command outside the input range, as a vented muscle's - at the range's
// nearest edge: from -5 V its integral rose through the muscle's first millimetres, where its gain is
// highest, and the loop swung for seconds at 50 Hz (docs/CONTROL.md, "From a vented muscle").
// So does a cycle whose estimator restarted or whose rollout was not finite, for kRecoverCycles after.
// While the estimator has lost the plant (its posterior far from the measured position) its modelling
// error is not followed: held where it was, the feedforward stays on (docs/CONTROL.md).
// Nor is it used while the model does not move as the muscle does (detail::ResponseMonitor): the model
// driven by the commands in effect beside the measured position, over the last second. A model with a
// tenth of the plant's gain tracked the triangle at 3x the PI's error before (docs/CONTROL.md, "A model
// that moves otherwise than the muscle").
// Nor at all, and no governor either, where the model does not come to rest under a held command at the loop's
// period (mbcModelRest): the MBC is then its nominal PI on the setpoint (docs/CONTROL.md, "A model that does not
// come to rest").
// The estimator's own restarts are not faults here: the PI keeps the loop meanwhile.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "control/controller.hpp"
#include "control/controller_parts.hpp"
#include "model/inverse_fold.hpp"

namespace pamc::control {

namespace {

// Cycles the feedforward stays off after the estimator restarted or its rollout failed.
constexpr int kRecoverCycles = 200;
// The phase the bus's delay may take at the PI's integral crossover: the 45 degrees of the textbook's phase
// margin, the other 45 left to the plant's own lag (chosen, not tuned: pi / 3 and pi / 2 were tried after,
// docs/CONTROL.md).
constexpr double kDelayPhase = 0.25 * M_PI;
// The least change per cycle of the feedforward of a folding model that does not carry the loop [V].
constexpr double kFoldFloor = 0.001;
// Secant steps of the inverse per cycle (warm-started from the last cycle's solution).
constexpr int kInverseSteps = 3;
// The estimator has lost the plant when its posterior output misses the position by more than this
// [output units] (chosen: with muscle_balance diagnosed on the calibrated physics plant the UKF of the form
// with the model's states in it (ActiveModelSettings::Q_d = 0) follows the paper's u0 within 0.0035 mm
// rms; with that plant's pneumatic_balance it has lost it, 4.5 mm rms. The default form, the modelling
// error on the position, follows both.)
constexpr double kLostBy = 1.0;
// The response monitor's window [s] and the span of the changes it compares [s] (chosen).
constexpr double kMonitorTau = 1.0;
constexpr double kMonitorSpan = 0.02;

// Two commands of the inverse's steps whose misses lie on either side of the target, once found.
struct Bracket {
  double u_last = NAN, miss_last = NAN;  // the last command tried, before the target was bracketed
  double u_a = NAN, miss_a = NAN, u_b = NAN, miss_b = NAN;
  bool found = false;
  // Takes a command and its miss; true once the target lies between two of them (the newer replaces the one
  // on its side).
  bool take(double u, double miss) noexcept {
    if (!found && miss * miss_last < 0.0) {
      found = true;
      u_a = u_last, miss_a = miss_last;
    }
    if (!found) {
      u_last = u, miss_last = miss;
      return false;
    }
    if ((miss > 0.0) == (miss_a > 0.0))
      u_a = u, miss_a = miss;
    else
      u_b = u, miss_b = miss;
    return true;
  }
  // The secant through them: a command between the two.
  double between() const noexcept { return u_b - miss_b * (u_b - u_a) / (miss_b - miss_a); }
};

class Mbc final : public detail::PiBased {
 public:
  explicit Mbc(const ControllerConfig& c)
      : cfg_(c),
        horizon_(mbcHorizon(c)),
        sign_(modelGainSign(c.model, c.Ts, c.u_min, c.u_max)),
        ff_(mbcCommandRange(c)),
        rests_(mbcModelRest(c).rests),
        fold_(model::inverseFold(c.model, ff_.lo, ff_.hi)) {
    pi_.configure(c, true);
    if (rests_) buildStatic();
    am_.configure(c.model, c.ukf, c.Ts);
    limits_ = mbcGovernor(c);
    governor_.configure(limits_.rate_mm_s, limits_.accel_mm_s2, c.Ts, c.mbc.rate_mm_s);  // lowered, it passes ramps
    doubt_decay_ = std::exp(-c.Ts / c.mbc.carried_tau_s);
    monitor_.configure(c.Ts, kMonitorTau, kMonitorSpan);
  }
  Kind kind() const override { return Kind::Mbc; }
  int lookahead() const override { return horizon_; }

  void activate(double u0, double y0) noexcept override {
    pi_.reset(startCommand(u0));
    y_.reset(y0);
    am_.reset(u0);
    hist_.fill(u0);
    u_ff_ = u_solved_ = u0;
    miss_ = 0.0;
    ff_hist_.fill(u0);
    ctx_.Ts = cfg_.Ts;
    cfg_.model.init(ref_, u0, ctx_);
    y_ref_ = cfg_.model.step(ref_, u0, ctx_);
    cfg_.model.init(act_, u0, ctx_);
    monitor_.reset();
    ff_on_ = started_ = false;
    recover_ = 0;
    gain_ = sign_;
    governor_.reset(y0);
    governor_.setAccel(limits_.accel_mm_s2);  // at rest: back to the fixed one
    doubt_ = 0.0;
    governed_.fill(std::isfinite(y0) ? y0 : NAN);
    r_prev_ = NAN;
  }

  ControlOutput update(double yd, double yd_ahead, double y, double load) noexcept override {
    ControlOutput o;
    const auto est = am_.update(hist_.get(cfg_.delay_cycles), y, load);
    o.y_hat = est.y_post;
    o.estimator_reset = false;  // a restart turns the feedforward off; it is not a fault of this loop
    o.measurement_rejected = est.rejected || !std::isfinite(y);
    if (!o.measurement_rejected) y_.take(y);
    const bool lost = !o.measurement_rejected && std::fabs(est.y_post - y) > kLostBy;
    if (est.status == estimation::UkfStatus::Reset) recover_ = kRecoverCycles;
    ctx_.load = load;
    if (!lost) followMiss(est);
    watchResponse(y, o.measurement_rejected);
    governor_.setAccel(carried() ? limits_.accel_carried_mm_s2 : limits_.accel_mm_s2);
    const double r = governor_.step(yd_ahead);
    governed_.push(r);
    const double ff = feedforward(r - miss_);
    const bool use =
        rests_ && recover_ == 0 && std::isfinite(ff) && inRange(ff, r, yd_ahead, y_.get()) && monitor_.trusted();
    if (recover_ > 0) --recover_;
    if (std::isfinite(ff))
      u_solved_ = ff;
    else
      recover_ = kRecoverCycles;
    switchFeedforward(use, use && ff_on_ ? heldAtFold(ff, r) : ff);
    r_prev_ = r;
    advanceReference(u_solved_);
    // The nominal PI on the governed setpoint's error (on the reference model's instead, a model that cannot
    // reach the setpoint held the loop short of it: docs/CONTROL.md).
    const double r_now = governed_.get(horizon_);
    pi_.scale(gainShare(std::isfinite(r_now) ? r_now : yd));
    const double un = pi_.nominal((std::isfinite(r_now) ? r_now : yd) - y_.get(), !o.measurement_rejected);
    o.u_c = ff_on_ ? u_ff_ : 0.0;
    o.model_distrusted = !monitor_.trusted();
    o.model_ratio = monitor_.ratio();
    o.governor_accel = governor_.accel();
    o.u = pi_.finish(un, o.u_c, o.saturated, o.u_n);
    hist_.push(o.u);
    doubt_ = std::max(ff_on_ ? std::fabs(pi_.integral()) : cfg_.u_max - cfg_.u_min, doubt_ * doubt_decay_);
    return o;
  }
  const estimation::ActiveModel* activeModel() const noexcept override { return &am_; }

 private:
  // The model's output `horizon_` samples on from the reference state: the feedforwards in flight first,
  // then u held.
  double rollout(double u) const noexcept {
    model::Model::State s = ref_;
    double y = y_ref_;
    const int d = cfg_.delay_cycles;
    for (int i = 0; i < horizon_; ++i) y = cfg_.model.step(s, i < d ? ff_hist_.get(d - 1 - i) : u, ctx_);
    return y;
  }

  // A model whose inverse folds (model::inverseFold), while it does not carry the loop: the feedforward moves per
  // cycle by at most twice the governed setpoint's change over the model's settled gain, and at least kFoldFloor
  // - its jump across the fold goes at the setpoint's pace (docs/CONTROL.md, "A model whose inverse folds").
  double heldAtFold(double ff, double r) const noexcept {
    if (!fold_.folds || carried() || !(std::fabs(fold_.gain) > 0.0) || !std::isfinite(r_prev_)) return ff;
    const double cap = std::max(2.0 * std::fabs(r - r_prev_) / std::fabs(fold_.gain), kFoldFloor);
    return std::clamp(ff, u_ff_ - cap, u_ff_ + cap);
  }

  // The static characteristic, or none (every share 1) where the model has no usable one.
  void buildStatic() {
    try {
      static_.build(cfg_.model, ff_.lo, ff_.hi, cfg_.Ts);
    } catch (const std::invalid_argument&) {
      static_ = InverseStatic();
    }
  }

  // The PI's gains' share at the setpoint r: the loop's integral crossover ki g (g the model's static slope
  // there) held where the commands in flight and the sample's hold, T = (delay_cycles + 1.5) Ts, take at most
  // kDelayPhase of its phase (docs/CONTROL.md, "The PI's gains where the muscle is stiff"). At 1 kHz
  // (T = 3.5 ms) it takes effect only beyond 75 mm/V.
  double gainShare(double r) const noexcept {
    const double g = static_.slope(r) * sign_;
    const double T = (cfg_.delay_cycles + 1.5) * cfg_.Ts;
    if (!rests_ || !(g > 0.0) || !(cfg_.ki > 0.0)) return 1.0;
    return std::min(1.0, kDelayPhase / (cfg_.ki * g * T));
  }

  // Where the PI starts: the command in effect, brought into the input range of a model that is used.
  double startCommand(double u0) const noexcept {
    return rests_ && cfg_.model.range().known && std::isfinite(u0) ? std::clamp(u0, ff_.lo, ff_.hi) : u0;
  }

  // The command that, held after the feedforwards in flight, brings the reference model to `target` at
  // the horizon; NaN if the rollout is not finite.
  double feedforward(double target) noexcept {
    double u = std::clamp(u_solved_, ff_.lo, ff_.hi);
    Bracket b;
    for (int step = 0; step < kInverseSteps; ++step) {
      const double yh = rollout(u);
      if (!std::isfinite(yh)) return NAN;
      const double miss = target - yh;
      // Once two commands miss on either side of the target, the next lies between them: a step along a slope
      // near 0 flew from one edge of the input range to the other, cycle after cycle (docs/CONTROL.md, "The
      // inverse's bracket").
      if (b.take(u, miss)) {
        u = b.between();
        continue;
      }
      // The slope in the direction the command will move (the loop's branches differ). A slope of the other
      // sign than the model's settled gain is not taken (the last one is kept): through the commands in flight a
      // model can answer a rise of the command with a fall at the horizon (a vented pneumatic model at 50 Hz),
      // and a step along it ran the reference model from stop to stop (docs/CONTROL.md, "At 50 Hz").
      const double du = std::copysign(0.01 * (cfg_.u_max - cfg_.u_min), miss);
      const double g = (rollout(u + du) - yh) / du;
      if (std::isfinite(g) && g * sign_ > 1e-3) gain_ = g;
      u = std::clamp(u + miss / gain_, ff_.lo, ff_.hi);
    }
    return u;
  }

  // The modelling error as the UKF sees it - its posterior output against the reference model's - through a
  // first-order filter of time constant mbc_error_tau_s: the feedforward aims the model that much off the
  // setpoint, so that the plant lands on it. A restart of the estimator leaves it where it was.
  void followMiss(const estimation::ActiveModelStep& est) noexcept {
    if (est.status == estimation::UkfStatus::Reset || !std::isfinite(est.y_post) || !std::isfinite(y_ref_)) return;
    miss_ += (est.y_post - y_ref_ - miss_) * std::min(1.0, cfg_.Ts / cfg_.mbc.error_tau_s);
  }

  // The response monitor's cycle: the model driven by the commands in effect beside the measured position,
  // judged only where the model was identified (from a vented muscle both fill from outside its range).
  void watchResponse(double y, bool rejected) noexcept {
    const double u = hist_.get(cfg_.delay_cycles);
    const double y_act = cfg_.model.step(act_, u, ctx_);
    const auto& r = cfg_.model.range();
    if (r.known && !(r.input.contains(u) && r.output.contains(y_act) && r.output.contains(y_.get())))
      monitor_.forget();
    else if (!rejected)
      monitor_.step(y_act, y);
  }

  // The model carries the loop: its feedforward on, the muscle moving as it says, and the PI's integral - the
  // part of the command the model did not predict - within carried_share of the command's span lately.
  bool carried() const noexcept {
    return ff_on_ && monitor_.trusted() && doubt_ <= cfg_.mbc.carried_share * (cfg_.u_max - cfg_.u_min);
  }

  // The reference model takes the feedforward that reaches its effect now (sent delay_cycles + 1 ago).
  void advanceReference(double ff) noexcept {
    ff_hist_.push(ff);
    y_ref_ = cfg_.model.step(ref_, ff_hist_.get(cfg_.delay_cycles), ctx_);
  }

  // Where the model was identified: the setpoint (ahead and governed) and the position within its output range, the
  // feedforward within its input range (the input rate is not asked: a setpoint step is faster than
  // any record). A model without a range is used everywhere (the controller said so at its start).
  bool inRange(double ff, double governed, double yd_ahead, double y) const noexcept {
    const auto& r = cfg_.model.range();
    if (!r.known) return true;
    return r.input.contains(ff) && r.output.contains(governed) && r.output.contains(yd_ahead) &&
           (!std::isfinite(y) || r.output.contains(y));
  }

  // Takes the feedforward in or out with the PI's integral moved by it, so the command does not jump - but
  // in the first cycle after activate() (the loop's start from the safe value, or a restart, where the
  // loop's slew limits the step) the feedforward is taken as the whole command, the integral 0 beside it.
  void switchFeedforward(bool use, double ff) noexcept {
    if (use && !ff_on_) pi_.shift(started_ ? -ff : -pi_.integral());
    if (!use && ff_on_) pi_.shift(u_ff_);
    ff_on_ = use;
    started_ = true;
    if (use) u_ff_ = ff;
  }

  ControllerConfig cfg_;
  int horizon_;
  double sign_;              // the sign of the model's settled response to a command step (modelGainSign)
  model::Interval ff_;       // the feedforward's bounds (mbcCommandRange)
  bool rests_;               // the model comes to rest under a held command (mbcModelRest): else the PI alone
  model::InverseFold fold_;  // whether its inverse folds over ff_ (heldAtFold)
  InverseStatic static_;     // the model's static characteristic over ff_ (its slope schedules the PI's gains)
  detail::LastGood y_;
  estimation::ActiveModel am_;
  detail::CommandHistory ff_hist_;  // the feedforwards sent, the reference model's input
  detail::SetpointGovernor governor_;
  GovernorLimits limits_;
  double doubt_ = 0.0;          // the PI integral's magnitude, a peak decaying by doubt_decay_ a cycle
  double doubt_decay_ = 1.0;    // exp(-Ts / carried_tau_s)
  detail::DelayLine governed_;  // the governed setpoint ahead, r(k), of the last cycles
  model::Model::State ref_;     // the reference model: the model driven by the feedforward alone
  model::Model::State act_;     // the model driven by the commands in effect (the monitor's)
  detail::ResponseMonitor monitor_;
  double y_ref_ = 0.0;  // its output now
  model::StepContext ctx_;
  double u_ff_ = 0.0;      // the feedforward in the command (the last one, while it is off)
  double u_solved_ = 0.0;  // the last finite solution of the inverse: the next cycle's start
  double gain_ = 1.0;      // the model's response at the horizon to a unit command change [mm/V]
  bool ff_on_ = false;     // the feedforward is in the command
  bool started_ = false;   // past the first cycle since activate()
  double r_prev_ = NAN;    // the governed setpoint of the last cycle
  double miss_ = 0.0;      // the modelling error: the UKF's posterior output - the reference model's, low-passed
  int recover_ = 0;        // cycles left with the feedforward off after an estimator restart
};

}  // namespace

int mbcHorizon(const ControllerConfig& c) {
  if (c.mbc.horizon > 0) return c.mbc.horizon;
  return responseHorizon(c);
}

std::unique_ptr<Controller> makeMbc(const ControllerConfig& cfg) { return std::make_unique<Mbc>(cfg); }

}  // namespace pamc::control
