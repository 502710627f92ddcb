// The sampled plant: the command held over each sample (after the delay and dead band, exact operators on
// the held signal), the ODE of the mode integrated by Boost.Odeint's RK4 at a fixed substep, the output
// effects that are static maps of the end state (warm_up), the end stops, and the sensor.
#include "physics/physics_plant.hpp"

#include <algorithm>
#include <cmath>

#include <boost/numeric/odeint/stepper/runge_kutta4.hpp>

#include "physics/dynamics.hpp"

namespace pamc::physics {

namespace {
using Stepper = boost::numeric::odeint::runge_kutta4<PhysicsState>;
}  // namespace

PhysicsPlant::PhysicsPlant(const PhysicsConfig& c) : cfg_(c), rng_(c.seed) {
  if (cfg_.effects.delay.enabled) {
    const double n = std::max(cfg_.effects.delay.d, 0.0) / cfg_.Ts;
    delay_whole_ = static_cast<int>(std::floor(n));
    delay_frac_ = n - std::floor(n);
    // Rounding: a delay within 1e-9 of a whole number of samples is that number (no split).
    if (delay_frac_ > 1.0 - 1e-9) {
      ++delay_whole_;
      delay_frac_ = 0.0;
    } else if (delay_frac_ < 1e-9) {
      delay_frac_ = 0.0;
    }
  }
  reset(0.0);
}

double PhysicsPlant::deadBand(double u) const noexcept {
  return cfg_.effects.dead_band.enabled ? std::max(u, cfg_.effects.dead_band.threshold) : u;
}

void PhysicsPlant::reset(double u0_V, double force_N) noexcept {
  if (!std::isfinite(u0_V)) u0_V = 0.0;
  if (!std::isfinite(force_N)) force_N = 0.0;
  u0_V = std::clamp(u0_V, cfg_.u_min, cfg_.u_max);
  u_last_ = u0_V;
  force_last_ = force_N;
  ring_.fill(u0_V);
  head_ = 0;
  t_ = 0.0;
  const double cmd = deadBand(u0_V);
  if (cfg_.mode == Mode::Rig) {
    RigModel(cfg_).rest(x_, cmd, force_N);
    y_start_ = RigModel(cfg_).contraction_mm(x_) + (cfg_.effects.creep.enabled ? x_[kCreepR] : 0.0);
  } else {
    ReferenceModel(cfg_).rest(x_, cmd, force_N);
    y_start_ = ReferenceModel(cfg_).output(x_);
  }
  y_ = output();
  rng_.seed(cfg_.seed);
  noise_.reset();
}

double PhysicsPlant::step(double u_V, double force_N) noexcept {
  if (!std::isfinite(u_V)) u_V = u_last_;  // a nonsense command holds the previous one
  if (!std::isfinite(force_N)) force_N = force_last_;
  u_V = std::clamp(u_V, cfg_.u_min, cfg_.u_max);
  u_last_ = u_V;
  force_last_ = force_N;
  head_ = (head_ + 1) & (kDelayRing - 1);
  ring_[static_cast<size_t>(head_)] = u_V;
  // The command seen delay d = (n + f) Ts late: over [t, t + f Ts) the one held n + 1 samples ago, over
  // [t + f Ts, t + Ts) the one held n samples ago (n = 0, f = 0 without the delay: this sample's).
  const auto at = [&](int back) { return ring_[static_cast<size_t>((head_ - back) & (kDelayRing - 1))]; };
  const double cmd_second = deadBand(at(delay_whole_));
  const double cmd_first = delay_frac_ > 0.0 ? deadBand(at(delay_whole_ + 1)) : cmd_second;
  integrate(cmd_first, cmd_second, delay_frac_ * cfg_.Ts, force_N);
  t_ += cfg_.Ts;
  y_ = output();
  return y_;
}

void PhysicsPlant::integrate(double cmd_first, double cmd_second, double t_switch, double force_N) noexcept {
  const int n = cfg_.activeSubsteps();
  const double h = cfg_.Ts / n;
  Stepper rk;  // its scratch states are std::arrays on the stack: no allocation
  if (cfg_.mode == Mode::Rig) {
    const RigModel m(cfg_);
    auto run = [&](double cmd, double t0, double dt) {
      rk.do_step([&](const PhysicsState& x, PhysicsState& dx, double) { m.rhs(x, dx, cmd, force_N); }, x_, t0, dt);
    };
    for (int i = 0; i < n; ++i) {
      const double t0 = i * h, t1 = (i + 1) * h;
      // The substep in which the delayed command switches is split at the switch.
      if (t_switch > t0 && t_switch < t1) {
        run(cmd_first, t0, t_switch - t0);
        m.project(x_);
        run(cmd_second, t_switch, t1 - t_switch);
      } else {
        run(t0 < t_switch ? cmd_first : cmd_second, t0, h);
      }
      m.project(x_);
    }
  } else {
    // Mode reference: the substeps of a piece (a part of the sample with the command held) are the
    // union of a uniform grid (reference_substeps / 4 per sample, for the slow dynamics) and grids
    // along the transients of the fast valve and force stages (for the rate-independent elements,
    // stiff in time while their input moves fast); those stages enter at their exact solutions.
    const ReferenceModel m(cfg_);
    const double tau = cfg_.reference.tau_valve_s;
    const int n_uniform = std::max(1, cfg_.reference_substeps / 4);
    const double h_uniform = cfg_.Ts / n_uniform;
    auto piece = [&](double cmd, double a, double b) {
      const ReferenceDrive d{cmd, x_[kV0], force_N, x_[kFf], a};
      // Transient grids, l = (t - a) / tau: l_{j+1} = l_j + u0 exp(l_j / 5) (see transientStepCommand).
      struct Transient {
        double u0, l = 0.0;
        double next(double t, double a, double tau) noexcept {
          if (u0 <= 0.0) return INFINITY;
          while (a + tau * l <= t && l < 60.0) l += u0 * std::exp(l / 5.0);
          return l < 60.0 ? a + tau * l : INFINITY;
        }
      };
      Transient tv{m.transientStepCommand(cmd - x_[kV0])}, tf{m.transientStepForce(force_N - x_[kFf])};
      int i_u = static_cast<int>(std::floor(a / h_uniform)) + 1;
      double t = a;
      while (t < b) {
        while (i_u * h_uniform <= t) ++i_u;
        const double next = std::min(std::min(b, i_u * h_uniform), std::min(tv.next(t, a, tau), tf.next(t, a, tau)));
        rk.do_step([&](const PhysicsState& x, PhysicsState& dx, double tt) { m.rhs(x, dx, d, tt); }, x_, t, next - t);
        m.setFastStages(x_, d, next);
        t = next;
      }
    };
    if (t_switch > 0.0 && t_switch < cfg_.Ts) {
      piece(cmd_first, 0.0, t_switch);
      piece(cmd_second, t_switch, cfg_.Ts);
    } else {
      piece(cmd_second, 0.0, cfg_.Ts);
    }
  }
}

double PhysicsPlant::output() const noexcept {
  double y;
  if (cfg_.mode == Mode::Rig) {
    y = RigModel(cfg_).contraction_mm(x_);
    if (cfg_.effects.creep.enabled) y += x_[kCreepR];
  } else {
    y = ReferenceModel(cfg_).output(x_);
  }
  const auto& w = cfg_.effects.warm_up;
  if (w.enabled) {
    // Closed form in the time since reset: y + phi (gain (y - y_start) + shift), phi = 1 - exp(-t / tau).
    const double phi = -std::expm1(-t_ / w.tau);
    y += phi * (w.gain * (y - y_start_) + w.shift);
  }
  if (cfg_.stroke_limits) y = std::clamp(y, cfg_.stroke_min_mm, cfg_.stroke_max_mm);
  return y;
}

double PhysicsPlant::measure() noexcept {
  double y = y_;
  if (cfg_.noise_std_mm > 0.0) y += cfg_.noise_std_mm * noise_(rng_);
  if (cfg_.quantum_mm > 0.0) y = std::round(y / cfg_.quantum_mm) * cfg_.quantum_mm;
  return y;
}

double PhysicsPlant::pressure_bar() const noexcept {
  if (cfg_.mode == Mode::Rig) return RigModel(cfg_).pressure_bar(x_);
  const double v = std::clamp(cfg_.regulator.setpoint_offset_V + ReferenceModel(cfg_).effectiveCommand(x_), 0.0, 10.0);
  return v * cfg_.regulator.setpoint_bar_per_V;
}

}  // namespace pamc::physics
