#include "sim/lockstep.hpp"

#include <algorithm>
#include <array>
#include <cmath>

#include "io/measurement.hpp"

namespace pamc::sim {

void Record::reserve(size_t n) {
  for (auto* v : {&t, &yd, &y, &y_true, &u, &u_n, &u_c, &y_hat, &force, &p}) v->reserve(n);
}

void Record::writeCsv(const std::string& path) const {
  io::writeCsvAtomic(path, {"t", "yd", "y", "y_true", "u", "u_n", "u_c", "y_hat", "load", "p"},
                     {&t, &yd, &y, &y_true, &u, &u_n, &u_c, &y_hat, &force, &p});
}

Lockstep::Lockstep(control::Controller& ctrl, plant::Plant& plant, const ClosedLoopRun& run, double u0, Hooks hooks)
    : ctrl_(ctrl),
      plant_(plant),
      run_(run),
      u0_(u0),
      hooks_(std::move(hooks)),
      Ts_(plant.config().Ts),
      n_(static_cast<long>(std::llround(run.duration_s / plant.config().Ts))),
      d_(std::clamp(run.delay_cycles, 0, 7)) {
  rec_.reserve(static_cast<size_t>(std::max(n_, 0L)));
}

double Lockstep::send(double u) {
  for (int i = 7; i > 0; --i) pipe_[static_cast<size_t>(i)] = pipe_[static_cast<size_t>(i - 1)];
  pipe_[0] = u;
  return pipe_[static_cast<size_t>(d_)];  // the valve applies what was sent d cycles ago
}

void Lockstep::start() {
  plant_.reset(u0_, 0.0);
  ctrl_.activate(u0_, plant_.measure());
  pipe_.fill(u0_);
  k_ = 0;
  const double y_home = run_.home();
  const auto n_pre = static_cast<size_t>(std::llround(std::max(run_.preroll_s, 0.0) / Ts_));
  for (size_t k = 0; k < n_pre; ++k) {
    const auto o = ctrl_.update(y_home, y_home, plant_.measure());
    plant_.step(send(o.u), 0.0);
  }
}

const control::ControlOutput& Lockstep::step() {
  const double t = static_cast<double>(k_) * Ts_;
  const double F = run_.force_step_time_s >= 0 && t >= run_.force_step_time_s ? run_.force_N : 0.0;
  const double y_read = plant_.measure();  // latch
  y_given_ = hooks_.measurement ? hooks_.measurement(k_, y_read) : y_read;
  const double yd = run_.reference.at(t);
  out_ = ctrl_.update(yd, run_.reference.at(t + ctrl_.lookahead() * Ts_), y_given_);  // estimate + control
  rec_.t.push_back(t);
  rec_.yd.push_back(yd);
  rec_.y.push_back(y_read);
  rec_.y_true.push_back(plant_.position());
  rec_.u.push_back(out_.u);
  rec_.u_n.push_back(out_.u_n);
  rec_.u_c.push_back(out_.u_c);
  rec_.y_hat.push_back(out_.y_hat);
  rec_.force.push_back(F);
  rec_.p.push_back(plant_.pressure_bar());
  double applied = send(out_.u);
  if (hooks_.valve) applied = hooks_.valve(k_, applied);
  plant_.step(applied, F);
  ++k_;
  return out_;
}

Record runClosedLoop(control::Controller& ctrl, plant::Plant& plant, const ClosedLoopRun& run, double u0) {
  Lockstep loop(ctrl, plant, run, u0);
  loop.start();
  while (!loop.done()) loop.step();
  return std::move(loop.record());
}

namespace {
// One open-loop sample: the command held for a sample, then the sensor read at its end.
void openLoopSample(plant::Plant& plant, Record& r, double t, double uk, double F) {
  plant.step(uk, F);
  r.t.push_back(t);
  r.yd.push_back(NAN);
  r.y.push_back(plant.measure());
  r.y_true.push_back(plant.position());
  r.u.push_back(uk);
  r.u_n.push_back(uk);
  r.u_c.push_back(0.0);
  r.y_hat.push_back(NAN);
  r.force.push_back(F);
  r.p.push_back(plant.pressure_bar());
}
}  // namespace

Record runOpenLoopInput(plant::Plant& plant, const Trajectory& u, double duration_s, const Trajectory* force_N) {
  const double Ts = plant.config().Ts;
  const auto n = static_cast<size_t>(std::llround(duration_s / Ts));
  Record r;
  r.reserve(n);
  plant.reset(u.at(0.0), force_N ? force_N->at(0.0) : 0.0);
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * Ts;
    openLoopSample(plant, r, t, u.at(t), force_N ? force_N->at(t) : 0.0);
  }
  return r;
}

Record runOpenLoopSamples(plant::Plant& plant, const std::vector<double>& u, const std::vector<double>* force_N) {
  Record r;
  if (u.empty()) return r;
  r.reserve(u.size());
  plant.reset(u[0], force_N ? (*force_N)[0] : 0.0);
  for (size_t k = 0; k < u.size(); ++k)
    openLoopSample(plant, r, static_cast<double>(k) * plant.config().Ts, u[k], force_N ? (*force_N)[k] : 0.0);
  return r;
}

TrackingStats tracking(const Record& r, double from_s) {
  TrackingStats s;
  double acc = 0;
  size_t n = 0;
  for (size_t i = 0; i < r.t.size(); ++i) {
    if (r.t[i] < from_s) continue;
    const double e = r.yd[i] - r.y[i];
    acc += e * e;
    s.max_abs = std::max(s.max_abs, std::fabs(e));
    ++n;
  }
  s.rmse = n ? std::sqrt(acc / static_cast<double>(n)) : 0.0;
  return s;
}

double firstReach(const Record& r) {
  if (r.t.empty()) return 0.0;
  const double e0 = r.yd[0] - r.y[0];
  for (size_t i = 0; i < r.t.size(); ++i)
    if ((r.yd[i] - r.y[i]) * e0 <= 0.0) return r.t[i];
  return r.t.back();
}

double scoredFrom(const Record& r, const ClosedLoopRun& run) { return run.startsAwayFromHome() ? firstReach(r) : 0.0; }

StepStats stepResponse(const Record& r, int dir, double min_jump, double band_frac) {
  StepStats s;
  double os_sum = 0, ts_sum = 0;
  const double Ts = r.t.size() > 1 ? r.t[1] - r.t[0] : 1e-3;
  for (size_t i = 1; i < r.t.size(); ++i) {
    const double jump = r.yd[i] - r.yd[i - 1];
    if (std::fabs(jump) < min_jump || (jump > 0) != (dir > 0)) continue;
    // The segment lasts until the next jump of the reference.
    size_t j = i + 1;
    while (j < r.t.size() && std::fabs(r.yd[j] - r.yd[j - 1]) < min_jump) ++j;
    const double target = r.yd[i];
    const bool ramp = std::fabs(r.yd[j - 1] - target) > 1e-9;  // sawtooth: target moves
    double peak = 0;
    size_t last_out = i;
    const double band = band_frac * std::fabs(jump);
    int side = -1, crossings = 0;  // the error starts short of the target
    const double cross_band = 0.01 * std::fabs(jump);
    int u_dir = 0, reversals = 0;
    double u_ext = 0.0;
    constexpr double kReversal_V = 0.05;
    const double kLowPass = 1.0 - std::exp(-2.0 * M_PI * 20.0 * Ts);
    double u_f = r.u[i - 1];
    for (size_t k = i; k < j; ++k) {
      const double e = (r.y[k] - r.yd[k]) * (dir > 0 ? 1 : -1);  // > 0: past the target
      peak = std::max(peak, e);
      if (std::fabs(r.y[k] - r.yd[k]) > band) last_out = k;
      if (!ramp && ((e > cross_band && side < 0) || (e < -cross_band && side > 0))) {
        side = -side;
        ++crossings;
      }
      // Direction reversals of the command, with a hysteresis of kReversal_V (u_dir 0: not yet moved),
      // seen through a 20 Hz first-order low-pass: ringing is an oscillation a valve and a muscle can
      // follow, not a decaying wobble at the sample rate that the regulator cannot.
      u_f += (r.u[k] - u_f) * kLowPass;
      const double u = u_f;
      if (u_dir == 0) {
        if (std::fabs(u - r.u[i - 1]) > kReversal_V) u_dir = u > r.u[i - 1] ? 1 : -1, u_ext = u;
      } else if ((u - u_ext) * u_dir > 0) {
        u_ext = u;
      } else if ((u_ext - u) * u_dir > kReversal_V) {
        u_dir = -u_dir, u_ext = u, ++reversals;
      }
    }
    s.max_error_crossings = std::max(s.max_error_crossings, crossings);
    s.max_u_reversals = std::max(s.max_u_reversals, reversals);
    if (j - i < 10) continue;
    if (last_out + 1 >= j) ++s.unsettled;
    os_sum += 100.0 * peak / std::fabs(jump);
    ts_sum += static_cast<double>(last_out + 1 - i) * Ts;
    ++s.steps;
  }
  if (s.steps) {
    s.overshoot_pct = os_sum / s.steps;
    s.settling_s = ts_sum / s.steps;
  }
  return s;
}

RecoveryStats recovery(const Record& r, double t_event, double band_mm) {
  RecoveryStats s;
  size_t last_out = 0;
  size_t i0 = 0;
  bool any = false;
  for (size_t i = 0; i < r.t.size(); ++i) {
    if (r.t[i] < t_event) continue;
    if (!any) i0 = i;
    any = true;
    const double e = std::fabs(r.y[i] - r.yd[i]);
    s.peak_dev_mm = std::max(s.peak_dev_mm, e);
    if (e > band_mm) last_out = i;
  }
  // Recovered only if the error then stays in the band for at least half a second before the end.
  const double Ts = r.t.size() > 1 ? r.t[1] - r.t[0] : 1e-3;
  const auto dwell = static_cast<size_t>(0.5 / Ts);
  if (any && last_out + dwell >= r.t.size()) s.recovered = false;
  if (any && last_out >= i0) s.recovery_s = r.t[last_out] - r.t[i0] + (r.t.size() > 1 ? r.t[1] - r.t[0] : 0);
  return s;
}

}  // namespace pamc::sim
