// mass_spring: the payload's inertia against the muscle's stiffness and damping makes the
// displacement a second-order response to the force balance (ringing after fast changes).
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"
#include "model/effects/second_order.hpp"

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
        {"fn", 0.2, 100.0, 10.0, "Hz"},
        {"zeta", 0.01, 3.0, 0.5, "-"},
    };
    return p;
  }
  // y, dy/dt, then the cached one-sample map [y v]' = A [y v] + B in (A row-major, B).
  int numStates() const override { return 8; }
  int numFilterStates() const override { return 2; }  // y, v: the core reaches y through them
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    secondOrderMap(p[0], p[1], c.Ts, s + 2);
    s[0] = in0;
    s[1] = 0.0;
  }
  double step(const double*, double* s, double in, const StepContext&) const noexcept override {
    const double y = s[2] * s[0] + s[3] * s[1] + s[6] * in;
    const double v = s[4] * s[0] + s[5] * s[1] + s[7] * in;
    s[0] = y;
    s[1] = v;
    return y;
  }
};

}  // namespace
std::unique_ptr<Effect> make_mass_spring() { return std::make_unique<MassSpring>(); }
}  // namespace pamc::model
