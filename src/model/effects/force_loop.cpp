// force_loop: a payload moved by the muscle, with the friction between tube and braid (and in the
// guide) inside the payload's force balance:
//
//   m y'' + c y' + k y + z = F,   dz = (zmax / delta) (1 - sgn(dy) z / zmax) dy
//
// divided by the stiffness k: y'' = wn^2 (in - y - z) - 2 zeta wn y', where the stage input
// in = F / k is the force balance's static displacement (what the Bouc-Wen core and the effects
// before this one deliver) and z is the friction force over the stiffness. z is a Bouc-Wen element
// of order n = 1 driven by the payload's own motion (A = zmax / delta, beta = 1 / delta, gamma = 0):
// it grows over a pre-sliding travel of about delta after every reversal and saturates at the
// Coulomb level zmax while sliding. So the friction both widens the loop (the payload sticks at
// reversals until the force has turned by 2 zmax) and acts on the ringing (it damps the
// oscillation and holds the payload short of the static position).
//
// It is the alternative to mass_spring, not an addition: with zmax = 0 it is mass_spring, and a
// model takes one or the other (Effect::alternativeTo). friction_hysteresis followed by mass_spring
// is the series chain, in which friction acts on the displacement before the inertia and cannot
// hold the ringing payload; this effect puts it into the same force balance.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class ForceLoop final : public Effect {
 public:
  const char* name() const override { return "force_loop"; }
  const char* explanation() const override {
    return "payload inertia with friction inside its force balance: the payload rings after fast changes and sticks at reversals";
  }
  Stage stage() const override { return Stage::Output; }
  // The payload's force balance takes everything upstream as its force: the last block of the
  // chain, at mass_spring's place.
  int rank() const override { return 40; }
  const char* alternativeTo() const override { return "mass_spring"; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"fn", 0.2, 100.0, 10.0, "Hz"},       // natural frequency of payload against stiffness
        {"zeta", 0.01, 3.0, 0.5, "-"},        // viscous damping ratio
        {"zmax", 0.0, 10.0, 0.5, "y-unit"},   // Coulomb friction force over stiffness
        {"delta", 0.01, 20.0, 0.5, "y-unit"}, // pre-sliding travel
    };
    return p;
  }
  int numStates() const override { return 3; }  // y, v = dy/dt, z
  // y and v: the core reaches the displacement through them (as in mass_spring); the friction
  // state follows the estimated motion with the filter's mean.
  int numFilterStates() const override { return 2; }
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override {
    s[0] = in0;
    s[1] = 0.0;
    s[2] = 0.0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double wn = 2.0 * M_PI * std::max(p[0], 1e-6);
    const double zeta = std::max(p[1], 0.0);
    const double zmax = std::fabs(p[2]);
    const double delta = std::max(p[3], 1e-9);
    const double a = zmax / delta;  // friction stiffness (over k) while sticking
    const double w2 = wn * wn;
    // Sub-steps short against the period, as mass_spring's (the same semi-implicit Euler, so with
    // zmax = 0 both give the same displacement). Clamped before the conversion, so a huge fn cannot
    // overflow the int (NaN takes one step).
    const double steps = std::ceil(wn * c.Ts / 0.05);
    const int n = steps >= 1.0 ? (steps < 2000.0 ? static_cast<int>(steps) : 2000) : 1;
    const double h = c.Ts / n;
    double y = s[0], v = s[1], z = s[2];
    if (a > 0.0) {
      for (int i = 0; i < n; ++i) {
        // Velocity without the friction's change over the sub-step; the friction then enters
        // implicitly (its force at the end of the sub-step), so a stiff pre-sliding spring
        // (small delta) cannot make the step unstable. The direction of motion is that of vs.
        const double vs = v + h * (w2 * (in - y - z) - 2.0 * zeta * wn * v);
        if (vs == 0.0) {
          v = 0.0;
          continue;
        }
        const double dir = vs > 0.0 ? 1.0 : -1.0;
        const double g = std::max(0.0, 1.0 - dir * z / zmax);
        v = vs / (1.0 + h * h * w2 * a * g);
        const double dy = h * v;
        y += dy;
        // The friction over the travel dy, exactly (it never passes the Coulomb level).
        z += (dir * zmax - z) * -std::expm1(-std::fabs(dy) / delta);
      }
    } else {
      for (int i = 0; i < n; ++i) {
        v += h * (w2 * (in - y) - 2.0 * zeta * wn * v);
        y += h * v;
      }
      z = 0.0;
    }
    s[0] = y;
    s[1] = v;
    s[2] = z;
    return y;
  }
};

}  // namespace
std::unique_ptr<Effect> make_force_loop() { return std::make_unique<ForceLoop>(); }
}  // namespace pamc::model
