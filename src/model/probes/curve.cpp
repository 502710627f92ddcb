// input_curve / output_curve: a monotone static characteristic on one side of the hysteresis. A
// piecewise-linear curve through six equal segments between two levels, with a positive slope per
// segment (normalised to a mean of 1, so the core's gain keeps the scale); outside the two levels the
// end segments continue. The identity when every slope is 1.
#include <algorithm>
#include <cmath>
#include <string>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class MonotoneCurve final : public Effect {
 public:
  explicit MonotoneCurve(Stage stage) : stage_(stage) {}
  const char* name() const override { return stage_ == Stage::Input ? "input_curve" : "output_curve"; }
  const char* explanation() const override {
    return stage_ == Stage::Input ? "probe: a monotone static curve between the command and the hysteresis"
                                  : "probe: a monotone static curve between the hysteresis and the displacement";
  }
  Stage stage() const override { return stage_; }
  int rank() const override { return stage_ == Stage::Input ? 1 : 99; }  // outermost on its side
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> in =
        withSlopes({{"lo", -10.0, 10.0, -5.0, "u-level"}, {"hi", -10.0, 10.0, 5.0, "u-level"}});
    static const std::vector<ParamSpec> out =
        withSlopes({{"lo", 0.0, 40.0, 5.0, "y-level"}, {"hi", 0.0, 40.0, 35.0, "y-level"}});
    return stage_ == Stage::Input ? in : out;
  }
  int numStates() const override { return 0; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    const double lo = std::min(p[0], p[1]), hi = std::max(p[0], p[1]);
    const double w = (hi - lo) / kSegments;
    if (!(w > 0.0)) return in;
    double s[kSegments], mean = 0.0;
    for (int j = 0; j < kSegments; ++j) mean += (s[j] = std::max(std::fabs(p[2 + j]), 1e-3));
    mean /= kSegments;
    if (in <= lo) return lo + s[0] / mean * (in - lo);
    double out = lo;
    for (int j = 0; j < kSegments; ++j) out += s[j] / mean * std::clamp(in - (lo + j * w), 0.0, w);
    if (in > hi) out += s[kSegments - 1] / mean * (in - hi);
    return out;
  }

 private:
  static constexpr int kSegments = 6;
  static std::vector<ParamSpec> withSlopes(std::vector<ParamSpec> p) {
    for (int j = 1; j <= kSegments; ++j) p.push_back({"s" + std::to_string(j), 0.1, 5.0, 1.0, "-"});
    return p;
  }
  Stage stage_;
};

}  // namespace
std::unique_ptr<Effect> make_input_curve() { return std::make_unique<MonotoneCurve>(Stage::Input); }
std::unique_ptr<Effect> make_output_curve() { return std::make_unique<MonotoneCurve>(Stage::Output); }
}  // namespace pamc::model
