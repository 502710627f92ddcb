// friction_hysteresis: Coulomb friction between the rubber tube and the braid (and in the guide)
// opposes the muscle's own motion; after each reversal the displacement sticks until the friction
// has turned round. A Dahl element driven by the output's motion, not by the input.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

// z after the stage's input moved by din (monotone within the sample), exactly. With y = in - z and
// dz = a g dy, a = zmax / delta, g = 1 - s z / zmax (s = sign(din)): dz/din = a g / (1 + a g). In
// q = 1 - s z / zmax that is separable, (1 + a q) / q dq = -(|din| / delta) ... in units of zmax:
// ln q + a q = ln q0 + a q0 - |din| / delta, solved for q by Newton's method in r = ln q (increasing and
// convex in r, so it converges from the one-step implicit estimate in two or three iterations). The
// one-step estimate alone was off by O((din / delta)^2) per sample: at a fast chirp and a short
// pre-sliding travel an independent continuous-time simulation saw it (tests/oracle).
double dahlAlongInput(double z0, double din, double zmax, double delta) noexcept {
  const double sgn = din > 0.0 ? 1.0 : -1.0;
  const double a = zmax / delta;
  const double q0 = std::max(0.0, 1.0 - sgn * z0 / zmax);
  if (q0 == 0.0) return sgn * zmax;  // sliding at the Coulomb level: stays there
  // The one-step implicit estimate, dy = din / (1 + a g0), as the start.
  const double dz0 = a * q0 * din / (1.0 + a * q0);
  const double q_start = std::clamp(1.0 - sgn * (z0 + dz0) / zmax, 1e-300, q0);
  const double c = std::log(q0) + a * q0 - std::fabs(din) / delta;
  double r = std::log(q_start);
  for (int i = 0; i < 20; ++i) {
    const double e = a * std::exp(r);
    const double step = (r + e - c) / (1.0 + e);
    r -= step;
    if (std::fabs(step) < 1e-13 * std::max(1.0, std::fabs(r))) break;
  }
  const double q = std::min(std::exp(r), q0);
  return std::clamp(sgn * zmax * (1.0 - q), -zmax, zmax);
}

class FrictionHysteresis final : public Effect {
 public:
  const char* name() const override { return "friction_hysteresis"; }
  const char* explanation() const override {
    return "friction in the force balance: after every reversal of the motion the muscle sticks until friction turns "
           "round";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 30; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"zmax", 0.0, 10.0, 0.5, "y-unit"},    // friction force over stiffness
        {"delta", 0.01, 20.0, 0.5, "y-unit"},  // pre-sliding travel
    };
    return p;
  }
  int numStates() const override { return 2; }  // z, previous input
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override {
    s[0] = 0.0;
    s[1] = in0;
  }
  double step(const double* p, double* s, double in, const StepContext&) const noexcept override {
    const double zmax = std::fabs(p[0]);
    const double din = in - s[1];
    s[1] = in;
    if (zmax > 0.0 && din != 0.0) {
      s[0] = dahlAlongInput(s[0], din, zmax, std::max(p[1], 1e-9));
    } else if (zmax == 0.0) {
      s[0] = 0.0;
    }
    return in - s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_friction_hysteresis() { return std::make_unique<FrictionHysteresis>(); }
}  // namespace pamc::model
