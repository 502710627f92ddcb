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

Record runClosedLoop(control::Controller& ctrl, plant::Plant& plant, const ClosedLoopRun& run, double u0) {
  const double Ts = plant.config().Ts;
  const auto n = static_cast<size_t>(std::llround(run.duration_s / Ts));
  Record r;
  r.reserve(n);
  plant.reset(u0, 0.0);
  ctrl.activate(u0, plant.measure());
  // Commands in flight to the valve (index 0 = applied this cycle).
  std::array<double, 8> pipe;
  pipe.fill(u0);
  const int d = std::clamp(run.delay_cycles, 0, 7);
  auto send = [&](double u) {
    for (int i = 7; i > 0; --i) pipe[static_cast<size_t>(i)] = pipe[static_cast<size_t>(i - 1)];
    pipe[0] = u;
    return pipe[static_cast<size_t>(d)];
  };
  const double y_home = run.reference.at(0.0);
  const auto n_pre = static_cast<size_t>(std::llround(std::max(run.preroll_s, 0.0) / Ts));
  for (size_t k = 0; k < n_pre; ++k) {
    const auto o = ctrl.update(y_home, y_home, plant.measure());
    plant.step(send(o.u), 0.0);
  }
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * Ts;
    const double F = run.force_step_time_s >= 0 && t >= run.force_step_time_s ? run.force_N : 0.0;
    const double y = plant.measure();                 // latch
    const auto o = ctrl.update(run.reference.at(t), run.reference.at(t + ctrl.lookahead() * Ts), y);  // estimate + control
    r.t.push_back(t);
    r.yd.push_back(run.reference.at(t));
    r.y.push_back(y);
    r.y_true.push_back(plant.position());
    r.u.push_back(o.u);
    r.u_n.push_back(o.u_n);
    r.u_c.push_back(o.u_c);
    r.y_hat.push_back(o.y_hat);
    r.force.push_back(F);
    r.p.push_back(plant.pressure_bar());
    // Send: the valve applies what was sent d cycles ago.
    plant.step(send(o.u), F);
  }
  return r;
}

Record runOpenLoopInput(plant::Plant& plant, const Trajectory& u, double duration_s, const Trajectory* force_N) {
  const double Ts = plant.config().Ts;
  const auto n = static_cast<size_t>(std::llround(duration_s / Ts));
  Record r;
  r.reserve(n);
  plant.reset(u.at(0.0), force_N ? force_N->at(0.0) : 0.0);
  for (size_t k = 0; k < n; ++k) {
    const double t = static_cast<double>(k) * Ts;
    const double uk = u.at(t);
    const double F = force_N ? force_N->at(t) : 0.0;
    plant.step(uk, F);
    const double y = plant.measure();
    r.t.push_back(t);
    r.yd.push_back(NAN);
    r.y.push_back(y);
    r.y_true.push_back(plant.position());
    r.u.push_back(uk);
    r.u_n.push_back(uk);
    r.u_c.push_back(0.0);
    r.y_hat.push_back(NAN);
    r.force.push_back(F);
    r.p.push_back(plant.pressure_bar());
  }
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
    (void)ramp;
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
