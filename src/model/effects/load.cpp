// load: an external force on the muscle (a payload on the hook) stretches it through its
// compliance; the displacement falls in proportion to the measured load column.
#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Load final : public Effect {
 public:
  const char* name() const override { return "load"; }
  const char* explanation() const override {
    return "compliance to an external load: the displacement drops in proportion to the measured load";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 10; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"compliance", -10.0, 10.0, 0.05, "y-unit/load-unit"}};
    return p;
  }
  int numStates() const override { return 0; }
  bool needsLoad() const override { return true; }
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext& c) const noexcept override {
    return in - p[0] * c.load;
  }
};

}  // namespace
std::unique_ptr<Effect> make_load() { return std::make_unique<Load>(); }
}  // namespace pamc::model
