// saturation: the braid angle approaches its locking angle near full contraction, so the muscle
// stiffens and the displacement flattens towards the end of the stroke.
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Saturation final : public Effect {
 public:
  const char* name() const override { return "saturation"; }
  const char* explanation() const override {
    return "stiffening towards the end of the stroke: above a knee the displacement flattens";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 20; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"knee", 0.0, 40.0, 30.0, "y-level"},
        {"width", 0.1, 80.0, 10.0, "y-unit"},
    };
    return p;
  }
  int numStates() const override { return 0; }
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    // Identity below the knee; above it a tanh that meets it with slope 1 and levels off
    // at knee + width.
    if (in <= p[0]) return in;
    const double w = p[1] > 1e-9 ? p[1] : 1e-9;
    // tanh(x) = (1 - e^-2x) / (1 + e^-2x) for x > 0: one exp (glibc's tanh, through expm1, took a
    // sixth of a fit's time); exact to rounding in the displacement (knee + w tanh).
    const double q = std::exp(-2.0 * (in - p[0]) / w);
    return p[0] + w * ((1.0 - q) / (1.0 + q));
  }
};

}  // namespace
std::unique_ptr<Effect> make_saturation() { return std::make_unique<Saturation>(); }
}  // namespace pamc::model
