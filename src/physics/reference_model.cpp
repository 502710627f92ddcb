// Mode reference: the paper's Bouc-Wen structure in continuous time, driven by the held command through
// a fast valve stage, with the continuous-time counterparts of the catalogue effects in the catalogue's
// chain order: input (delay, dead_band: applied to the held command by the plant; pressure_lag here),
// core, output (asymmetry, load, saturation, creep, friction_hysteresis, mass_spring | force_loop; warm_up
// is applied by the plant at the sample's end). Equations: docs/PHYSICS.md, section "Mode reference".
#include <algorithm>
#include <cmath>

#include "physics/dynamics.hpp"

namespace pamc::physics {

namespace {
constexpr double kTwoPi = 6.28318530717958647692;
double sgn(double v) noexcept { return v > 0.0 ? 1.0 : v < 0.0 ? -1.0 : 0.0; }
}  // namespace

ReferenceModel::ReferenceModel(const PhysicsConfig& c)
    : c_(&c), wn_ms_(kTwoPi * c.effects.mass_spring.fn), wn_fl_(kTwoPi * c.effects.force_loop.fn) {
  const auto& e = c.effects;
  const auto& r = c.reference;
  // dh/dv = alpha - c h with |c| <= |beta| + |gamma|: the core's rate per volt of travel.
  stiff_per_V_ = std::fabs(r.beta) + std::fabs(r.gamma);
  if (e.asymmetry.enabled) stiff_per_V_ = std::max(stiff_per_V_, 1.0 / std::min(e.asymmetry.w_up, e.asymmetry.w_down));
  if (e.friction_hysteresis.enabled && e.friction_hysteresis.zmax > 0.0) {
    // dz/d(in) ~ 1 / delta; the stage input moves by at most |dY/dv| per volt (h and the asymmetry's
    // element move by at most about twice their alpha per volt).
    const double dy_dv = (std::fabs(r.k * r.rho) + 2.0 * std::fabs(r.k * (1.0 - r.rho) * r.alpha) +
                          (e.asymmetry.enabled ? 2.0 * std::fabs(e.asymmetry.gain) : 0.0)) *
                         (e.creep.enabled ? 1.0 + std::fabs(e.creep.fraction) : 1.0);
    stiff_per_V_ = std::max(stiff_per_V_, dy_dv / e.friction_hysteresis.delta);
    if (e.load.enabled) stiff_per_N_ = std::fabs(e.load.compliance) / e.friction_hysteresis.delta;
  }
}

namespace {
// The first step along a transient, in units of tau_valve_s (0: no transient). Later steps grow as
// l_{j+1} = l_j + u0 exp(l_j / 5) (l = elapsed time / tau): each step then makes the same quadrature error
// (u^5 times the travel left) - 4th order in u0 - until the uniform grid takes over. u0 = 50 / substeps
// (0.25 at 200), smaller where the stiffest rate-independent element would move by more than 0.05 of its
// own scale in the first step (10 / (travel rate substeps)), and at least 0.2 / substeps.
double firstStep(double travel, double rate, int substeps) noexcept {
  if (!(travel > 0.0)) return 0.0;
  const double s = static_cast<double>(substeps);
  double u0 = 50.0 / s;
  if (travel * rate > 0.0) u0 = std::min(u0, 10.0 / (travel * rate * s));
  return std::max(u0, 0.2 / s);
}
}  // namespace

double ReferenceModel::transientStepCommand(double dv_V) const noexcept {
  return firstStep(std::fabs(dv_V), stiff_per_V_, c_->reference_substeps);
}

double ReferenceModel::transientStepForce(double df_N) const noexcept {
  return c_->effects.load.enabled ? firstStep(std::fabs(df_N), stiff_per_N_, c_->reference_substeps) : 0.0;
}

void ReferenceModel::setFastStages(PhysicsState& x, const ReferenceDrive& d, double t) const noexcept {
  const double decay = std::exp(-(t - d.t_start) / c_->reference.tau_valve_s);
  x[kV0] = d.cmd + (d.v0_start - d.cmd) * decay;
  x[kFf] = d.force + (d.f_start - d.force) * decay;
}

double ReferenceModel::effectiveCommand(const PhysicsState& x) const noexcept {
  return c_->effects.pressure_lag.enabled ? x[kPl] : x[kV0];
}

void ReferenceModel::rhs(const PhysicsState& x_in, PhysicsState& dx, const ReferenceDrive& d, double t) const noexcept {
  const auto& e = c_->effects;
  const auto& r = c_->reference;
  dx.fill(0.0);
  // Input: the valve stage follows the held command (dv0/dt = (cmd - v0) / tau_valve, taken at its exact
  // solution); pressure_lag follows the valve stage with a first-order lag whose rate is limited to +-slew.
  PhysicsState x = x_in;
  setFastStages(x, d, t);
  dx[kV0] = (d.cmd - x[kV0]) / r.tau_valve_s;
  double vdot = dx[kV0];
  if (e.pressure_lag.enabled) {
    dx[kPl] = std::clamp((x[kV0] - x[kPl]) / e.pressure_lag.tau, -e.pressure_lag.slew, e.pressure_lag.slew);
    vdot = dx[kPl];
  }
  // Core: dh/dt = alpha v' - beta v' |h| - gamma |v'| h.
  const double h = x[kH];
  dx[kH] = r.alpha * vdot - r.beta * vdot * std::fabs(h) - r.gamma * std::fabs(vdot) * h;
  // The load reaches the output through the same fast stage, so a step of it is continuous too.
  dx[kFf] = (d.force - x[kFf]) / r.tau_valve_s;
  // Asymmetry: dz/dv = 1 - z / w_up while v rises, 1 + z / w_down while it falls.
  if (e.asymmetry.enabled)
    dx[kZa] = vdot > 0.0 ? vdot * (1.0 - x[kZa] / e.asymmetry.w_up) : vdot * (1.0 + x[kZa] / e.asymmetry.w_down);
  chain(x, &dx, nullptr);
}

double ReferenceModel::chain(const PhysicsState& x, PhysicsState* dx, PhysicsState* rest) const noexcept {
  const auto& e = c_->effects;
  const auto& r = c_->reference;
  const double v = effectiveCommand(x);
  const double vdot = dx ? (e.pressure_lag.enabled ? (*dx)[kPl] : (*dx)[kV0]) : 0.0;
  // Core output and its time derivative (the derivative feeds friction_hysteresis).
  double y = r.k * r.rho * v + r.b + r.k * (1.0 - r.rho) * x[kH];
  double yd = dx ? r.k * r.rho * vdot + r.k * (1.0 - r.rho) * (*dx)[kH] : 0.0;
  if (e.asymmetry.enabled) {
    y += e.asymmetry.gain * x[kZa];
    if (dx) yd += e.asymmetry.gain * (*dx)[kZa];
  }
  if (e.load.enabled) {
    y -= e.load.compliance * x[kFf];
    if (dx) yd -= e.load.compliance * (*dx)[kFf];
  }
  if (e.saturation.enabled && y > e.saturation.knee) {
    // knee + width tanh((y - knee) / width), through q = exp(-2 (y - knee) / width).
    const double w = e.saturation.width;
    const double q = std::exp(-2.0 * (y - e.saturation.knee) / w);
    y = e.saturation.knee + w * (1.0 - q) / (1.0 + q);
    yd *= 4.0 * q / ((1.0 + q) * (1.0 + q));
  }
  if (e.creep.enabled) {
    // Standard linear solid: z relaxes towards fraction x input with time constant tau.
    if (rest) (*rest)[kZc] = e.creep.fraction * y;
    const double z = rest ? (*rest)[kZc] : x[kZc];
    if (dx) (*dx)[kZc] = (e.creep.fraction * y - z) / e.creep.tau;
    y += z;
    if (dx) yd += (*dx)[kZc];
  }
  if (e.friction_hysteresis.enabled && e.friction_hysteresis.zmax > 0.0) {
    // Dahl element driven by the output's own motion: y = in - z, dz = a g dy, so
    // dz/dt = a g / (1 + a g) d(in)/dt with g = max(0, 1 - sgn(d in) z / zmax), a = zmax / delta.
    if (rest) (*rest)[kZf] = 0.0;
    const double z = rest ? 0.0 : x[kZf];
    if (dx) {
      const double zmax = e.friction_hysteresis.zmax;
      const double a = zmax / e.friction_hysteresis.delta;
      const double g = std::max(0.0, 1.0 - sgn(yd) * z / zmax);
      (*dx)[kZf] = a * g / (1.0 + a * g) * yd;
      yd -= (*dx)[kZf];
    }
    y -= z;
  }
  if (e.mass_spring.enabled) {
    // Payload: y'' = wn^2 (in - y) - 2 zeta wn y'.
    if (rest) {
      (*rest)[kMy] = y;
      (*rest)[kMyd] = 0.0;
    }
    const PhysicsState& s = rest ? *rest : x;
    if (dx) {
      (*dx)[kMy] = s[kMyd];
      (*dx)[kMyd] = wn_ms_ * wn_ms_ * (y - s[kMy]) - 2.0 * e.mass_spring.zeta * wn_ms_ * s[kMyd];
    }
    y = s[kMy];
  } else if (e.force_loop.enabled) {
    // Payload with friction in its force balance: y'' = wn^2 (in - y - z) - 2 zeta wn y',
    // dz/dt = (zmax / delta) (1 - sgn(y') z / zmax) y'  (z: friction force over stiffness).
    if (rest) {
      (*rest)[kMy] = y;
      (*rest)[kMyd] = 0.0;
      (*rest)[kFz] = 0.0;
    }
    const PhysicsState& s = rest ? *rest : x;
    if (dx) {
      const double zmax = e.force_loop.zmax;
      (*dx)[kMy] = s[kMyd];
      (*dx)[kMyd] = wn_fl_ * wn_fl_ * (y - s[kMy] - s[kFz]) - 2.0 * e.force_loop.zeta * wn_fl_ * s[kMyd];
      (*dx)[kFz] =
          zmax > 0.0 ? zmax / e.force_loop.delta * std::max(0.0, 1.0 - sgn(s[kMyd]) * s[kFz] / zmax) * s[kMyd] : 0.0;
    }
    y = s[kMy];
  }
  return y;
}

double ReferenceModel::output(const PhysicsState& x) const noexcept { return chain(x, nullptr, nullptr); }

void ReferenceModel::rest(PhysicsState& x, double cmd, double force_N) const noexcept {
  x.fill(0.0);
  x[kV0] = cmd;
  x[kPl] = cmd;
  x[kFf] = force_N;
  PhysicsState r = x;
  chain(x, nullptr, &r);
  x = r;
}

}  // namespace pamc::physics
