// rate_limit: the effective command follows the command no faster than a slew rate.
// rate_gain: the command's deviation from a centre level is scaled by 1 + g r / (r + r0), where r is
// the input's speed |du/dt| smoothed over tau: a gain that grows (g > 0) or falls (g < 0) with the
// speed and returns to 1 at rest.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class RateLimit final : public Effect {
 public:
  const char* name() const override { return "rate_limit"; }
  const char* explanation() const override { return "probe: the effective command changes no faster than a slew rate"; }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 35; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"slew", 0.5, 1000.0, 100.0, "u-unit/s"}};
    return p;
  }
  int numStates() const override { return 2; }  // output, cached step limit
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    s[0] = in0;
    retune(p, s, c);
  }
  bool directional() const override { return true; }
  bool followsInput() const override { return true; }
  void retune(const double* p, double* s, const StepContext& c) const noexcept override {
    s[1] = std::fabs(p[0]) * c.Ts;
  }
  double step(const double*, double* s, double in, const StepContext&) const noexcept override {
    s[0] += std::clamp(in - s[0], -s[1], s[1]);
    return s[0];
  }
};

class RateGain final : public Effect {
 public:
  const char* name() const override { return "rate_gain"; }
  const char* explanation() const override { return "probe: the command's gain changes with its speed"; }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 36; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"g", -0.8, 2.0, 0.0, "-"},
        {"r0", 0.05, 50.0, 1.0, "u-unit/s"},
        {"tau", 0.005, 2.0, 0.05, "s"},
        {"centre", -10.0, 10.0, 0.0, "u-level"},
    };
    return p;
  }
  int numStates() const override { return 3; }  // smoothed speed, previous input, cached filter gain
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    s[0] = 0.0;
    s[1] = in0;
    retune(p, s, c);
  }
  bool directional() const override { return true; }
  void retune(const double* p, double* s, const StepContext& c) const noexcept override {
    s[2] = 1.0 - std::exp(-c.Ts / std::max(p[2], 1e-6));
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    s[0] += s[2] * (std::fabs(in - s[1]) / c.Ts - s[0]);
    s[1] = in;
    const double r0 = std::max(std::fabs(p[1]), 1e-9);
    return p[3] + (in - p[3]) * (1.0 + p[0] * s[0] / (s[0] + r0));
  }
};

}  // namespace
std::unique_ptr<Effect> make_rate_limit() { return std::make_unique<RateLimit>(); }
std::unique_ptr<Effect> make_rate_gain() { return std::make_unique<RateGain>(); }
}  // namespace pamc::model
