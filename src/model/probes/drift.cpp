// drift: the displacement changes with the time since the start, not with the input: with
// phi = 1 - exp(-t / T), an offset a phi and a change g phi of the travel from where the record
// started, both settling, and a steady trend of c per 100 s.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Drift final : public Effect {
 public:
  const char* name() const override { return "drift"; }
  const char* explanation() const override {
    return "probe: an offset and a gain that change with time (settling and trend)";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 98; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"a", -20.0, 20.0, 0.0, "y-unit"},
        {"g", -0.5, 0.5, 0.0, "-"},
        {"T", 0.01, 1000.0, 10.0, "s"},
        {"c", -20.0, 20.0, 0.0, "y-unit"},  // per 100 s
    };
    return p;
  }
  int numStates() const override { return 2; }  // time since the start, stage input at the start
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override {
    s[0] = 0.0;
    s[1] = in0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double t = s[0];
    s[0] += c.Ts;
    const double phi = 1.0 - std::exp(-t / std::max(p[2], 1e-9));
    return in + phi * (p[1] * (in - s[1]) + p[0]) + p[3] * t / 100.0;
  }
};

}  // namespace
std::unique_ptr<Effect> make_drift() { return std::make_unique<Drift>(); }
}  // namespace pamc::model
