// creep: the rubber is viscoelastic - under a held pressure the muscle keeps drifting slowly
// towards a further fraction of its displacement.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Creep final : public Effect {
 public:
  const char* name() const override { return "creep"; }
  const char* explanation() const override { return "slow viscoelastic drift of the rubber under a held pressure"; }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 25; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"fraction", -0.5, 0.5, 0.05, "-"},  // further displacement, as a fraction of the displacement, once crept
        {"tau", 0.2, 200.0, 5.0, "s"},
    };
    return p;
  }
  // A standard-linear-solid creep: the extra displacement z relaxes towards fraction x input with
  // time constant tau, so after a change the muscle keeps drifting the same way; at rest it is a
  // gain change the core absorbs. States: z, cached filter gain.
  int numStates() const override { return 2; }
  int numFilterStates() const override { return 1; }  // z
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    s[0] = p[0] * in0;
    retune(p, s, c);
  }
  bool directional() const override { return true; }  // creep that differs loading and unloading
  void retune(const double* p, double* s, const StepContext& c) const noexcept override {
    s[1] = 1.0 - std::exp(-c.Ts / std::max(p[1], 1e-6));
  }
  double step(const double* p, double* s, double in, const StepContext&) const noexcept override {
    s[0] += s[1] * (p[0] * in - s[0]);
    return in + s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_creep() { return std::make_unique<Creep>(); }
}  // namespace pamc::model
