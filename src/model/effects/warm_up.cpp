// warm_up: the rubber tube warms after the start (its hysteresis losses heat it) and softens, so the
// muscle's travel from where it started grows and its length shifts, both settling with the tube's
// thermal time constant: y = y_in + phi (gain (y_in - y_start) + shift), phi = 1 - exp(-t / tau), t
// since the start. A record that starts warm shows none of it (phi would be 1 throughout).
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class WarmUp final : public Effect {
 public:
  const char* name() const override { return "warm_up"; }
  const char* explanation() const override {
    return "the rubber warms after the start and softens: travel grows and the length shifts with a thermal time "
           "constant";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 60; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"tau", 1.0, 3600.0, 60.0, "s"},        // thermal time constant of the tube
        {"gain", -0.5, 0.5, 0.1, "-"},          // relative change of the travel when warm
        {"shift", -10.0, 10.0, 0.0, "y-unit"},  // change of the length when warm
    };
    return p;
  }
  int numStates() const override { return 2; }  // time since the start, displacement at the start
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override {
    s[0] = 0.0;
    s[1] = in0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double phi = 1.0 - std::exp(-s[0] / std::max(p[0], 1e-9));
    s[0] += c.Ts;
    return in + phi * (p[1] * (in - s[1]) + p[2]);
  }
};

}  // namespace
std::unique_ptr<Effect> make_warm_up() { return std::make_unique<WarmUp>(); }
}  // namespace pamc::model
