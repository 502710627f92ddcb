// asymmetry: the muscle's loop is not point-symmetric - contracting (pressure rising) and relaxing
// it turns round differently, because filling and venting, and the braid's loading and unloading,
// differ. An extra hysteretic element of the command whose branches saturate at different widths.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Asymmetry final : public Effect {
 public:
  const char* name() const override { return "asymmetry"; }
  const char* explanation() const override {
    return "a different loop shape while contracting and while relaxing (branches turn round at different rates)";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 5; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"gain", -10.0, 10.0, 1.0, "y-unit/u-unit"},
        {"w_up", 0.05, 10.0, 1.0, "u-unit"},    // command travel to turn round while contracting
        {"w_down", 0.05, 10.0, 0.3, "u-unit"},  // ... while relaxing
    };
    return p;
  }
  int numStates() const override { return 2; }  // z [u-units], previous effective command
  void init(const double*, double* s, double, const StepContext& c) const noexcept override {
    s[0] = 0.0;
    s[1] = c.u_eff;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double du = c.u_eff - s[1];
    s[1] = c.u_eff;
    const double wu = std::max(p[1], 1e-6), wd = std::max(p[2], 1e-6);
    // Rising: z -> +w_up with dz/du = 1 - z / w_up; falling: z -> -w_down. Exact per step.
    if (du > 0)
      s[0] = wu - (wu - s[0]) * std::exp(-du / wu);
    else if (du < 0)
      s[0] = -wd + (s[0] + wd) * std::exp(du / wd);
    return in + p[0] * s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_asymmetry() { return std::make_unique<Asymmetry>(); }
}  // namespace pamc::model
