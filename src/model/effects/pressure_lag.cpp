// pressure_lag: the proportional valve and the muscle volume fill and vent through a restriction,
// so the pressure (and with it the effective command) follows the valve command with a first-order
// lag and a limited slew rate. Makes the hysteresis loop rate-dependent.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class PressureLag final : public Effect {
 public:
  const char* name() const override { return "pressure_lag"; }
  const char* explanation() const override {
    return "valve and muscle volume pressure dynamics: the pressure lags the command, so the loop widens with rate";
  }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 30; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"tau", 1e-3, 2.0, 0.05, "s"},
        {"slew", 1.0, 1000.0, 1000.0, "u-unit/s"},
    };
    return p;
  }
  int numStates() const override { return 3; }  // pressure (as command), cached: filter gain, step limit
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    s[0] = in0;
    retune(p, s, c);
  }
  bool directional() const override { return true; }   // a muscle filling and venting through different paths
  bool followsInput() const override { return true; }  // the pressure: filling while the command is above it
  void retune(const double* p, double* s, const StepContext& c) const noexcept override {
    s[1] = 1.0 - std::exp(-c.Ts / std::max(p[0], 1e-6));
    s[2] = std::max(p[1], 0.0) * c.Ts;
  }
  double step(const double*, double* s, double in, const StepContext&) const noexcept override {
    const double d = std::clamp((in - s[0]) * s[1], -s[2], s[2]);
    s[0] += d;
    return s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_pressure_lag() { return std::make_unique<PressureLag>(); }
}  // namespace pamc::model
