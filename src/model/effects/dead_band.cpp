// dead_band: the rubber's pre-tension and the valve's cracking pressure - below a threshold
// command the muscle does not move at all.
#include <algorithm>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class DeadBand final : public Effect {
 public:
  const char* name() const override { return "dead_band"; }
  const char* explanation() const override {
    return "no motion below a threshold input: the command is cut off at the threshold";
  }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 20; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"threshold", -5.0, 5.0, -5.0, "u-level"}};
    return p;
  }
  int numStates() const override { return 0; }
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    return std::max(in, p[0]);
  }
};

}  // namespace
std::unique_ptr<Effect> make_dead_band() { return std::make_unique<DeadBand>(); }
}  // namespace pamc::model
