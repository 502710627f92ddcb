#include "control/controller.hpp"
#include "control/controller_parts.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pamc::control {

const char* toString(Kind k) {
  switch (k) {
    case Kind::OpenLoop: return "open";
    case Kind::PI: return "pi";
    case Kind::PidEso: return "eso";
    case Kind::PiAmc: return "amc";
    case Kind::Input: return "input";
    case Kind::Mbc: return "mbc";
  }
  return "?";
}

Kind kindFromString(const std::string& s) {
  if (s == "open" || s == "openloop" || s == "open-loop") return Kind::OpenLoop;
  if (s == "pi" || s == "pid") return Kind::PI;
  if (s == "eso" || s == "pid+eso" || s == "pideso") return Kind::PidEso;
  if (s == "amc" || s == "pi+amc" || s == "pid+amc" || s == "piamc") return Kind::PiAmc;
  if (s == "input") return Kind::Input;
  if (s == "mbc") return Kind::Mbc;
  throw std::invalid_argument("unknown controller '" + s + "' (known: open, pi, eso, amc, mbc, input)");
}

// ---------------------------------------------------------------- inverse static characteristic
void InverseStatic::build(const model::Model& m, double u_min, double u_max, double Ts) {
  constexpr int kGrid = 201;
  const double period = 200.0;  // s: slow against every dynamic effect of a PAM
  const double dt = std::max(Ts, 5e-3);
  const auto n = static_cast<size_t>(period / dt);
  model::Model::State st;
  model::StepContext c;
  c.Ts = dt;
  m.init(st, u_min, c);
  std::vector<double> up(kGrid, NAN), dn(kGrid, NAN);
  const double du = (u_max - u_min) / (kGrid - 1);
  // Two full cycles; record the second so the loop is settled.
  for (int cycle = 0; cycle < 2; ++cycle) {
    for (size_t i = 0; i < n; ++i) {
      const double ph = static_cast<double>(i) / static_cast<double>(n);
      const double u = ph < 0.5 ? u_min + (u_max - u_min) * 2.0 * ph : u_max - (u_max - u_min) * (2.0 * ph - 1.0);
      const double y = m.step(st, u, c);
      if (cycle == 1) {
        const int g = std::clamp(static_cast<int>(std::lround((u - u_min) / du)), 0, kGrid - 1);
        (ph < 0.5 ? up : dn)[static_cast<size_t>(g)] = y;
      }
    }
  }
  u_.clear();
  y_.clear();
  double last = -INFINITY;
  for (int g = 0; g < kGrid; ++g) {
    const double a = up[static_cast<size_t>(g)], b = dn[static_cast<size_t>(g)];
    double y = std::isnan(a) ? b : std::isnan(b) ? a : 0.5 * (a + b);
    if (std::isnan(y)) continue;
    if (y <= last) y = last + 1e-9;  // monotonic so the inverse is a function
    last = y;
    u_.push_back(u_min + g * du);
    y_.push_back(y);
  }
  if (u_.size() < 2) throw std::invalid_argument("model has no usable static characteristic");
}

double InverseStatic::operator()(double y) const noexcept {
  if (y <= y_.front()) return u_.front();
  if (y >= y_.back()) return u_.back();
  const auto it = std::upper_bound(y_.begin(), y_.end(), y);
  const size_t i = static_cast<size_t>(it - y_.begin());
  const double t = (y - y_[i - 1]) / (y_[i] - y_[i - 1]);
  return u_[i - 1] + t * (u_[i] - u_[i - 1]);
}

double InverseStatic::slope(double y) const noexcept {
  if (u_.size() < 2) return 0.0;
  const auto it = std::upper_bound(y_.begin() + 1, y_.end() - 1, y);
  const size_t i = static_cast<size_t>(it - y_.begin());
  return (y_[i] - y_[i - 1]) / (u_[i] - u_[i - 1]);
}

double InverseStatic::forward(double u) const noexcept {
  if (u <= u_.front()) return y_.front();
  if (u >= u_.back()) return y_.back();
  const auto it = std::upper_bound(u_.begin(), u_.end(), u);
  const size_t i = static_cast<size_t>(it - u_.begin());
  const double t = (u - u_[i - 1]) / (u_[i] - u_[i - 1]);
  return y_[i - 1] + t * (y_[i] - y_[i - 1]);
}

namespace {
// The model's response to a step of a tenth of the command's range up from the middle, approached from
// below so the step continues the same branch of the loop: y0 before it, then kSteps samples.
struct StepResponse {
  static constexpr int kSteps = 2000;
  double y0 = 0.0;
  std::vector<double> y;
};
StepResponse stepResponse(const model::Model& m, double Ts, double u_min, double u_max) {
  const double u0 = 0.5 * (u_min + u_max), du = 0.1 * (u_max - u_min);
  model::Model::State st;
  model::StepContext c;
  c.Ts = Ts;
  m.init(st, u0 - du, c);
  StepResponse r;
  const int settle = static_cast<int>(std::ceil(2.0 / Ts));
  for (int i = 0; i < settle; ++i) r.y0 = m.step(st, u0 - du + du * std::min(1.0, 2.0 * i / settle), c);
  r.y.resize(StepResponse::kSteps);
  for (auto& y : r.y) y = m.step(st, u0 + du, c);
  return r;
}
}  // namespace

int modelResponseSamples(const model::Model& m, double Ts, double u_min, double u_max, double fraction) {
  const StepResponse r = stepResponse(m, Ts, u_min, u_max);
  const double span = r.y.back() - r.y0;
  const double target = r.y0 + fraction * span;
  for (int i = 0; i < StepResponse::kSteps; ++i)
    if ((r.y[static_cast<size_t>(i)] - target) * span >= 0.0) return i + 1;
  return StepResponse::kSteps;
}

double modelGainSign(const model::Model& m, double Ts, double u_min, double u_max) {
  const StepResponse r = stepResponse(m, Ts, u_min, u_max);
  return r.y.back() >= r.y0 ? 1.0 : -1.0;
}

// The commands in flight, then the command held for the model's 10 % response time - and for longer than
// the commands in flight act: at 50 and 100 Hz a pneumatic model makes 10 % of its response within one or
// two samples, and an inverse whose held command acted no longer than the two in flight drove the
// reference model from one end of the command's range to the other (docs/CONTROL.md, "At 50 Hz").
int responseHorizon(const ControllerConfig& c) {
  const int held = std::max(modelResponseSamples(c.model, c.Ts, c.u_min, c.u_max, 0.1), c.delay_cycles + 1);
  return std::min(2000, c.delay_cycles + held);
}

namespace {
constexpr double kPaceTs = 1e-3;
constexpr int kPaceSpan = 10;    // samples of each difference
constexpr int kPaceInstant = 5;  // a model that makes 90 % of the step within this many samples has no pace
constexpr int kPaceHold = 2000;  // samples each level is held

// The fastest speed and acceleration along one step of the command (the model's state carried in st), in
// the direction of the output's settled change; speed 0 where the output makes 90 % of it at once.
ModelPace paceOfStep(const model::Model& m, model::Model::State& st, const model::StepContext& c, double u,
                     double& y_now) {
  // The output at rest before the step for two spans, so the speed's first rise counts too (a lag whose
  // pressure slews at once reaches its speed within the first span).
  constexpr int kRest = 2 * kPaceSpan;
  const double y_before = y_now;
  std::vector<double> y(kRest + kPaceHold, y_before);
  for (int i = kRest; i < kRest + kPaceHold; ++i) y[static_cast<size_t>(i)] = m.step(st, u, c);
  y_now = y.back();
  const double span = y.back() - y_before, sign = span >= 0.0 ? 1.0 : -1.0;
  ModelPace p;
  int at90 = kPaceHold;
  for (int i = 0; i < kPaceHold && at90 == kPaceHold; ++i)
    if ((y[static_cast<size_t>(kRest + i)] - y_before) * sign >= 0.9 * std::fabs(span)) at90 = i;
  if (!std::isfinite(span) || span == 0.0 || at90 < kPaceInstant) return p;
  auto speed = [&](int i) {
    return sign * (y[static_cast<size_t>(i)] - y[static_cast<size_t>(i - kPaceSpan)]) / (kPaceSpan * kPaceTs);
  };
  for (int i = kRest; i < kRest + kPaceHold; ++i) {
    p.speed = std::max(p.speed, speed(i));
    p.accel = std::max(p.accel, (speed(i) - speed(i - kPaceSpan)) / (kPaceSpan * kPaceTs));
  }
  return p;
}
}  // namespace

ModelPace modelPace(const model::Model& m, double u_lo, double u_hi) {
  model::Model::State st;
  model::StepContext c;
  c.Ts = kPaceTs;
  m.init(st, u_lo, c);
  double y = 0.0;
  for (int i = 0; i < kPaceHold; ++i) y = m.step(st, u_lo, c);
  const ModelPace up = paceOfStep(m, st, c, u_hi, y);
  const ModelPace down = paceOfStep(m, st, c, u_lo, y);
  ModelPace p;
  if (up.speed > 0.0 && down.speed > 0.0 && std::isfinite(up.speed + down.speed + up.accel + down.accel))
    p = {std::min(up.speed, down.speed), std::min(up.accel, down.accel)};
  return p;
}

model::Interval mbcCommandRange(const ControllerConfig& c) {
  const auto& r = c.model.range();
  const model::Interval b{std::max(c.u_min, r.input.lo), std::min(c.u_max, r.input.hi)};
  return r.known && b.lo <= b.hi ? b : model::Interval{c.u_min, c.u_max};
}

model::HeldRest mbcModelRest(const ControllerConfig& c) {
  const model::Interval u = mbcCommandRange(c);
  return model::heldRest(c.model, c.Ts, u.lo, u.hi);
}

GovernorLimits mbcGovernor(const ControllerConfig& c) {
  const double carried = std::max(c.mbc.accel_carried_mm_s2, c.mbc.accel_mm_s2);
  if (!(c.mbc.rate_mm_s > 0.0) || !mbcModelRest(c).rests) return {0.0, c.mbc.accel_mm_s2, carried, false, {}};
  if (c.mbc.pace_share > 0.0) {
    const model::Interval u = mbcCommandRange(c);
    const ModelPace p = modelPace(c.model, u.lo, u.hi);
    const double rate = c.mbc.pace_share * p.speed, accel = c.mbc.pace_share * p.accel;
    if (!(p.speed > 0.0 && p.accel > 0.0)) return {c.mbc.rate_mm_s, c.mbc.accel_mm_s2, carried, false, p};
    const bool lowered = rate < c.mbc.rate_mm_s || accel < c.mbc.accel_mm_s2;
    return {std::min(rate, c.mbc.rate_mm_s), std::min(accel, c.mbc.accel_mm_s2), std::min(accel, carried), lowered, p};
  }
  return {c.mbc.rate_mm_s, c.mbc.accel_mm_s2, carried, false, {}};
}

int amcHorizon(const ControllerConfig& c) {
  if (c.amc_bus_aware) return c.delay_cycles + 1;
  if (c.amc_horizon > 0) return c.amc_horizon;
  if (c.amc_inverse <= 0.0) return 1;
  return responseHorizon(c);
}

void validate(const ControllerConfig& c) {
  auto bad = [](const std::string& what) { throw std::invalid_argument("controller configuration: " + what); };
  if (!(c.Ts > 0 && std::isfinite(c.Ts))) bad("Ts must be positive");
  if (!(c.u_min < c.u_max)) bad("u_min must be below u_max");
  for (double g : {c.kp, c.ki, c.kc, c.eso.beta1, c.eso.beta2, c.eso.beta3})
    if (!std::isfinite(g) || g < 0) bad("gains must be finite and non-negative");
  if (!(c.eso.delta > 0) || !(c.eso.b0 > 0)) bad("ESO delta and b0 must be positive");
  if (c.eso.order != 1 && c.eso.order != 2) bad("eso_order must be 1 (first-order plant) or 2 (eq. 22 as printed)");
  if (!(c.eso.gain > 0 && c.eso.tau > 0 && c.eso.wo > 0) || !std::isfinite(c.eso.gain + c.eso.tau + c.eso.wo))
    bad("ESO gain, time constant and bandwidth must be positive");
  if (c.delay_cycles < 0 || c.delay_cycles > 7) bad("delay_cycles must be 0..7");
  if (c.amc_horizon < 0 || c.amc_horizon > 2000) bad("amc_horizon must be 0 (automatic) .. 2000 samples");
  if (!(c.amc_inverse >= 0.0 && c.amc_inverse <= 1.0)) bad("amc_inverse must be in [0, 1]");
  if (c.mbc.horizon < 0 || c.mbc.horizon > 2000) bad("mbc_horizon must be 0 (automatic) .. 2000 samples");
  if (!(c.mbc.error_tau_s > 0.0) || !std::isfinite(c.mbc.error_tau_s)) bad("mbc_error_tau_s must be positive");
  if (!(c.mbc.rate_mm_s >= 0.0) || !std::isfinite(c.mbc.rate_mm_s)) bad("mbc_rate_mm_s must be 0 (off) or positive");
  if (!(c.mbc.accel_mm_s2 > 0.0) || !std::isfinite(c.mbc.accel_mm_s2)) bad("mbc_accel_mm_s2 must be positive");
  if (!(c.mbc.accel_carried_mm_s2 > 0.0) || !std::isfinite(c.mbc.accel_carried_mm_s2))
    bad("mbc_accel_carried_mm_s2 must be positive");
  if (!(c.mbc.pace_share >= 0.0 && c.mbc.pace_share <= 1.0)) bad("mbc_pace_share must be in [0, 1]");
  if (c.mbc.horizon > 0 && c.mbc.horizon <= c.delay_cycles)
    bad("mbc_horizon must be above delay_cycles (the command must act within the horizon)");
  if (c.amc_bus_aware && (c.amc_inverse > 0.0 || c.amc_horizon > 1))
    bad("the bus-aware AMC is the paper's form (amc_inverse 0) at the horizon delay_cycles + 1 (amc_horizon 0 or 1)");
  if (c.amc_inverse > 0.0 && c.amc_horizon > 0 && c.amc_horizon <= c.delay_cycles)
    bad("the predictive AMC needs amc_horizon above delay_cycles (the command must act within the horizon)");
}

namespace {

using detail::CommandHistory;
using detail::LastGood;
using detail::PiCore;

class OpenLoop final : public Controller {
 public:
  explicit OpenLoop(const ControllerConfig& c) : cfg_(c) {
    inv_.build(c.model, c.u_min, c.u_max, c.Ts);
    if (c.open_loop_linear) {
      // Least-squares line y = a + g u through the static characteristic on a uniform grid of u.
      constexpr int kN = 101;
      double su = 0, sy = 0, suu = 0, suy = 0;
      for (int i = 0; i < kN; ++i) {
        const double u = c.u_min + (c.u_max - c.u_min) * i / (kN - 1), y = inv_.forward(u);
        su += u, sy += y, suu += u * u, suy += u * y;
      }
      gain_ = (kN * suy - su * sy) / (kN * suu - su * su);
      offset_ = (sy - gain_ * su) / kN;
      if (!(std::fabs(gain_) > 1e-9) || !std::isfinite(offset_))
        throw std::invalid_argument("open loop: the model's static characteristic has no slope");
    }
  }
  Kind kind() const override { return Kind::OpenLoop; }
  void activate(double, double) noexcept override {}
  ControlOutput update(double yd, double, double, double) noexcept override {
    ControlOutput o;
    const double u = cfg_.open_loop_linear ? (yd - offset_) / gain_ : inv_(yd);
    o.u = o.u_n = std::clamp(u, cfg_.u_min, cfg_.u_max);
    o.y_hat = cfg_.open_loop_linear ? offset_ + gain_ * o.u : inv_.forward(o.u);
    return o;
  }

 private:
  ControllerConfig cfg_;
  InverseStatic inv_;
  double gain_ = 1.0, offset_ = 0.0;  // the linear inverse's line [mm/V], [mm]
};

// The identification input straight to the valve: u = yd within the valve's range. Nothing is estimated;
// y_hat is the measured position, so a record shows what the sensor gave.
class Input final : public Controller {
 public:
  explicit Input(const ControllerConfig& c) : u_min_(c.u_min), u_max_(c.u_max) {}
  Kind kind() const override { return Kind::Input; }
  void activate(double, double) noexcept override {}
  ControlOutput update(double u_wanted, double, double y, double) noexcept override {
    ControlOutput o;
    o.u = o.u_n = std::clamp(u_wanted, u_min_, u_max_);
    o.saturated = o.u != u_wanted;
    o.y_hat = y;
    return o;
  }

 private:
  double u_min_, u_max_;
};

class Pi final : public Controller {
 public:
  explicit Pi(const ControllerConfig& c) { pi_.configure(c); }
  Kind kind() const override { return Kind::PI; }
  void activate(double u0, double y0) noexcept override {
    pi_.reset(u0);
    y_.reset(y0);
  }
  ControlOutput update(double yd, double, double y, double) noexcept override {
    ControlOutput o;
    const bool ok = y_.take(y);
    o.measurement_rejected = !ok;
    const double un = pi_.nominal(yd - y_.get(), ok);
    o.u = pi_.finish(un, 0.0, o.saturated, o.u_n);
    o.y_hat = y_.get();
    return o;
  }
  void limited(double u_applied) noexcept override { pi_.limited(u_applied); }
  double integral() const noexcept override { return pi_.integral(); }

 private:
  PiCore pi_;
  LastGood y_;
};

// The AMC's estimator is the paper's, [h, f_h], whatever model it is given: its compensation is computed
// from h and f_h. With the modelling error taken on the position instead (ActiveModelSettings::Q_d, the
// MBC's form), eq. (17)'s prediction is the model's own output for the nominal command plus d, and the
// compensation fed back on itself through the model's direct feedthrough: over the bus at 50 Hz, with a
// model diagnosed from the plant's u0 record, 20.5 mm against 1.54 (docs/CONTROL.md, "At 50 Hz").
estimation::ActiveModelSettings papersForm(estimation::ActiveModelSettings s) {
  s.Q_d = 0.0;
  return s;
}

// PI + active model compensation, eqs. (14)-(19).
class PiAmc final : public detail::PiBased {
 public:
  explicit PiAmc(const ControllerConfig& c) : cfg_(c) {
    pi_.configure(c);
    am_.configure(c.model, papersForm(c.ukf), c.Ts);
    cfg_.amc_horizon = amcHorizon(c);
  }
  Kind kind() const override { return Kind::PiAmc; }
  int lookahead() const override { return cfg_.amc_horizon; }
  void activate(double u0, double y0) noexcept override {
    un_prev_ = u0;
    settled_ = 0;
    rate_ = 0.0;
    pi_.reset(u0);
    y_.reset(y0);
    am_.reset(u0);
    hist_.fill(u0);
    model::StepContext ctx;
    ctx.Ts = cfg_.Ts;
    cfg_.model.init(nom_, u0, ctx);
    un_eff_prev_ = nom_.u_eff_prev;
  }
  ControlOutput update(double yd, double yd_next, double y, double load) noexcept override {
    ControlOutput o;
    // Latch -> estimate: the command in effect when y was sampled.
    const auto est = am_.update(hist_.get(cfg_.delay_cycles), y, load);
    o.y_hat = est.y_post;
    o.estimator_reset = est.status == estimation::UkfStatus::Reset;
    // A model used outside the range it was identified on (model.json's `range`) may lose its estimator
    // there, or soon after: a restart is not a fault of this loop unless the filter has run inside the
    // range for a settling time since it last started - the filter starts over on the position and the
    // loop runs on. Settled inside the range, or with a model that records no range, a restart stays a
    // fault (the run goes to its safe state), as in the paper's form. (The lockstep experiments never
    // stop on a restart: for them nothing changes.)
    rate_ += ((hist_.get(0) - hist_.get(1)) / cfg_.Ts - rate_) * std::min(1.0, cfg_.Ts / kRateTau_s);
    settled_ = outsideRange(y) ? 0 : settled_ + 1;
    if (o.estimator_reset && cfg_.model.range().known && settled_ < settleCycles()) o.estimator_reset = false;
    if (est.status == estimation::UkfStatus::Reset) settled_ = 0;
    // A position the UKF did not use (not finite, or an outlier) is not used by the PI either: it
    // works with the last usable position and holds its integral. (Not with the UKF's prediction: with
    // a model whose output dynamics the filter cannot follow, that can be far off.)
    o.measurement_rejected = est.rejected || !std::isfinite(y);
    if (!o.measurement_rejected) y_.take(y);
    // Nominal PI, eq. (16).
    const double un = pi_.nominal(yd - y_.get(), !o.measurement_rejected);
    // Prediction, eq. (17): the nominal command's own increment drives the hysteresis.
    model::StepContext ctx;
    ctx.Ts = cfg_.Ts;
    ctx.load = load;
    double y_next;
    const int d = cfg_.delay_cycles;
    if (cfg_.amc_inverse > 0.0) {
      const auto in_flight = inFlight();
      // Predictive form: the commands already on their way first, then the nominal command held.
      y_next = am_.predictAhead(in_flight.data(), d, un, cfg_.amc_horizon, load);
      if (std::isfinite(y_next)) {
        // Slope of the response in the direction the correction will move (hysteresis differs).
        const double du = std::copysign(0.02 * (cfg_.u_max - cfg_.u_min), yd_next - y_next);
        const double g = (am_.predictAhead(in_flight.data(), d, un + du, cfg_.amc_horizon, load) - y_next) / du;
        if (std::isfinite(g) && std::fabs(g) > 1e-3) inverse_gain_ = g;
      }
    } else if (cfg_.amc_bus_aware) {
      // Eq. (17) through the bus: the commands on their way, then one step of the nominal command
      // (the horizon is delay_cycles + 1, amcHorizon).
      y_next = am_.predictAhead(inFlight().data(), d, un, cfg_.amc_horizon, load);
    } else if (cfg_.amc_horizon <= 1) {
      const double un_eff = cfg_.model.inputStage(nom_, un, ctx);
      y_next = cfg_.amc_as_printed ? am_.predictNextAsPrinted(un_eff_prev_, un_eff, load)
                                   : am_.predictNext(un_eff_prev_, un_eff, load);
      un_eff_prev_ = un_eff;
    } else {
      // Roll out from the last command sent plus the nominal controller's change.
      const double u_hold = hist_.get(0) + (un - un_prev_);
      y_next = am_.predictAhead(u_hold, cfg_.amc_horizon, load);
    }
    un_prev_ = un;
    // Compensation, eq. (18), and total command, eqs. (14)/(19).
    if (!std::isfinite(y_next))
      o.u_c = 0.0;
    else if (cfg_.amc_inverse > 0.0)
      o.u_c = std::clamp(cfg_.amc_inverse * (yd_next - y_next) / inverse_gain_, cfg_.u_min - cfg_.u_max,
                         cfg_.u_max - cfg_.u_min);
    else
      o.u_c = cfg_.kc * (yd_next - y_next);
    o.u = pi_.finish(un, o.u_c, o.saturated, o.u_n);
    hist_.push(o.u);
    return o;
  }
  const estimation::ActiveModel* activeModel() const noexcept override { return &am_; }

 private:
  // How long a filter started from a state outside the model's range runs inside it before a restart
  // counts as the model's failure where it holds (a chosen time, not a measured one: 1 s, a thousand
  // samples at the paper's 1 kHz, fifty at 50 Hz).
  static constexpr double kSettle_s = 1.0;
  // The command's rate is the motion's, not its noise's: through a first-order filter of 0.1 s.
  static constexpr double kRateTau_s = 0.1;
  std::uint64_t settleCycles() const noexcept { return static_cast<std::uint64_t>(std::lround(kSettle_s / cfg_.Ts)); }

  // The position (not finite, or outside), the last command or its rate outside the model's range;
  // never for a model that records none.
  bool outsideRange(double y) const noexcept {
    const auto& r = cfg_.model.range();
    if (!r.known) return false;
    return !std::isfinite(y) || r.check(hist_.get(0), y, rate_) != model::RangeExcess::None;
  }

  // The commands still on their way (delay_cycles of them), the oldest first.
  std::array<double, 8> inFlight() const noexcept {
    std::array<double, 8> c{};
    const int d = cfg_.delay_cycles;
    for (int j = 0; j < d; ++j) c[static_cast<size_t>(j)] = hist_.get(d - 1 - j);
    return c;
  }

  ControllerConfig cfg_;
  LastGood y_;
  estimation::ActiveModel am_;
  model::Model::State nom_;
  double un_eff_prev_ = 0.0;
  double un_prev_ = 0.0;
  double inverse_gain_ = 1.0;  // model's response at the horizon to a unit command change [mm/V]
  std::uint64_t settled_ = 0;  // cycles in a row inside the model's range since the filter last started
  double rate_ = 0.0;          // the command's rate, filtered [V/s]
};

// PID + extended state observer, eqs. (22)-(25), on the plant model eso_order says.
class PidEso final : public detail::PiBased {
 public:
  explicit PidEso(const ControllerConfig& c) : cfg_(c) { pi_.configure(c); }
  Kind kind() const override { return Kind::PidEso; }
  void activate(double u0, double y0) noexcept override {
    pi_.reset(u0);
    hist_.fill(u0);
    y_.reset(y0);
    x1_ = std::isfinite(y0) ? y0 : 0.0;
    x2_ = 0.0;
    x3_ = 0.0;
    sat_dir_ = 0;
    if (cfg_.eso.order == 1 && std::isfinite(u0)) {
      // At rest: the disturbance that holds x1 under u0, and the PI carrying the rest (bumpless).
      x2_ = (x1_ - cfg_.eso.gain * u0) / cfg_.eso.tau;
      pi_.reset(u0 - compensation());
    }
  }
  // u_c of eq. (25): the disturbance estimate in volts.
  double compensation() const noexcept {
    return cfg_.eso.order == 1 ? -x2_ * cfg_.eso.tau / cfg_.eso.gain : -x3_ / cfg_.eso.b0;
  }
  static double fal(double e, double a, double delta) noexcept {
    const double ae = std::fabs(e);
    return ae <= delta ? e / std::pow(delta, 1.0 - a) : std::copysign(std::pow(ae, a), e);
  }
  ControlOutput update(double yd, double, double y, double) noexcept override {
    ControlOutput o;
    // Observer, eq. (24), explicit Euler at Ts with the command in effect.
    const double Ts = cfg_.Ts;
    const double u_applied = hist_.get(cfg_.delay_cycles);
    // Without a usable position the observer runs on its model alone (no correction) and the PI
    // works with the last usable position, its integral held.
    const bool ok = y_.take(y);
    o.measurement_rejected = !ok;
    const double e = ok ? x1_ - y : 0.0;
    double x1, x2, x3 = 0.0;
    if (cfg_.eso.order == 1) {
      // (s + wo)^2 for the error: l1 + 1/T = 2 wo, l2 = wo^2.
      const double T = cfg_.eso.tau, wo = cfg_.eso.wo;
      x1 = x1_ + Ts * ((cfg_.eso.gain * u_applied - x1_) / T + x2_ - (2.0 * wo - 1.0 / T) * e);
      x2 = x2_ - Ts * wo * wo * e;
      // Conditional integration, as the PI's: while the command sits in a limit, the estimate does not
      // move the compensation further into it (a valve that does not follow would otherwise be taken
      // for a growing disturbance, to be given back at wo after it recovers).
      if (sat_dir_ != 0 && (x2_ - x2) * sat_dir_ > 0.0) x2 = x2_;
    } else {
      x1 = x1_ + Ts * (x2_ - cfg_.eso.beta1 * e);
      x2 = x2_ + Ts * (cfg_.eso.b0 * u_applied + x3_ - cfg_.eso.beta2 * fal(e, 0.5, cfg_.eso.delta));
      x3 = x3_ + Ts * (-cfg_.eso.beta3 * fal(e, 0.25, cfg_.eso.delta));
    }
    if (std::isfinite(x1) && std::isfinite(x2) && std::isfinite(x3)) {
      x1_ = x1;
      x2_ = x2;
      x3_ = x3;
    } else {
      x1_ = std::isfinite(y_.get()) ? y_.get() : 0.0;
      x2_ = x3_ = 0.0;
      o.estimator_reset = true;
    }
    o.y_hat = x1_;
    const double un = pi_.nominal(yd - y_.get(), ok);
    // Eq. (25): u = u_n - the disturbance in volts.
    o.u_c = compensation();
    o.u = pi_.finish(un, o.u_c, o.saturated, o.u_n);
    sat_dir_ = !o.saturated ? 0 : o.u >= cfg_.u_max ? 1 : -1;
    hist_.push(o.u);
    return o;
  }
  double disturbance() const noexcept override { return cfg_.eso.order == 1 ? x2_ : x3_; }

 private:
  ControllerConfig cfg_;
  LastGood y_;
  double x1_ = 0, x2_ = 0, x3_ = 0;
  int sat_dir_ = 0;  // the last command: +1 in the upper limit, -1 in the lower, 0 inside
};

}  // namespace

std::unique_ptr<Controller> makeController(Kind kind, const ControllerConfig& cfg) {
  validate(cfg);
  switch (kind) {
    case Kind::OpenLoop: return std::make_unique<OpenLoop>(cfg);
    case Kind::PI: return std::make_unique<Pi>(cfg);
    case Kind::PidEso: return std::make_unique<PidEso>(cfg);
    case Kind::PiAmc: return std::make_unique<PiAmc>(cfg);
    case Kind::Input: return std::make_unique<Input>(cfg);
    case Kind::Mbc: return makeMbc(cfg);
  }
  throw std::invalid_argument("unknown controller kind");
}

}  // namespace pamc::control
