// mass_spring: the payload's inertia against the muscle's stiffness and damping makes the
// displacement a second-order response to the force balance (ringing after fast changes).
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class MassSpring final : public Effect {
 public:
  const char* name() const override { return "mass_spring"; }
  const char* explanation() const override {
    return "payload inertia: second-order mechanical dynamics between force balance and displacement";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 40; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"fn", 0.05, 200.0, 10.0, "Hz"},
        {"zeta", 0.01, 3.0, 0.5, "-"},
    };
    return p;
  }
  int numStates() const override { return 2; }  // y, dy/dt
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override {
    s[0] = in0;
    s[1] = 0.0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double wn = 2.0 * M_PI * std::max(p[0], 1e-6);
    const double zeta = std::max(p[1], 0.0);
    // Semi-implicit Euler with sub-steps short against the period keeps it stable and accurate.
    int n = static_cast<int>(std::ceil(wn * c.Ts / 0.05));
    n = std::clamp(n, 1, 200);
    const double h = c.Ts / n;
    double y = s[0], v = s[1];
    for (int i = 0; i < n; ++i) {
      const double acc = wn * wn * (in - y) - 2.0 * zeta * wn * v;
      v += acc * h;
      y += v * h;
    }
    s[0] = y;
    s[1] = v;
    return y;
  }
};

}  // namespace
std::unique_ptr<Effect> make_mass_spring() { return std::make_unique<MassSpring>(); }
}  // namespace pamc::model
