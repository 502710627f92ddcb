// friction_hysteresis: Coulomb friction between the rubber tube and the braid (and in the guide)
// opposes the muscle's own motion; after each reversal the displacement sticks until the friction
// has turned round. A Dahl element driven by the output's motion, not by the input.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class FrictionHysteresis final : public Effect {
 public:
  const char* name() const override { return "friction_hysteresis"; }
  const char* explanation() const override {
    return "friction in the force balance: after every reversal of the motion the muscle sticks until friction turns round";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 30; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"zmax", 0.0, 10.0, 0.5, "y-unit"},  // friction force over stiffness
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
      const double a = zmax / std::max(p[1], 1e-9);
      const double g = std::max(0.0, 1.0 - std::copysign(1.0, din) * s[0] / zmax);
      // Implicit in the output motion: dy = din - dz, dz = a g dy.
      const double dy = din / (1.0 + a * g);
      s[0] = std::clamp(s[0] + a * g * dy, -zmax, zmax);
    } else if (zmax == 0.0) {
      s[0] = 0.0;
    }
    return in - s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_friction_hysteresis() { return std::make_unique<FrictionHysteresis>(); }
}  // namespace pamc::model
