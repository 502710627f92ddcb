// The classic hard nonlinearities of actuators and sensors (Tao and Kokotovic, adaptive control of
// systems with nonsmooth nonlinearities): a dead zone, a hard clip and a piecewise-linear gain on the
// command, and backlash (play) between the muscle and the sensor. Static but for backlash's one state.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

// No response within +-width of the centre; outside, the command shifted towards the centre by the
// width (so the characteristic is continuous).
class DeadZone final : public Effect {
 public:
  const char* name() const override { return "dead_zone"; }
  const char* explanation() const override { return "probe: a band of the command around a centre with no response"; }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 2; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"centre", -10.0, 10.0, 0.0, "u-level"},
                                             {"width", 0.0, 3.0, 0.2, "u-unit"}};
    return p;
  }
  int numStates() const override { return 0; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    const double e = in - p[0], w = std::fabs(p[1]);
    if (std::fabs(e) <= w) return p[0];
    return in - (e > 0 ? w : -w);
  }
};

// The command clipped to [lo, hi]: a regulator whose range ends before the command's.
class CommandClip final : public Effect {
 public:
  const char* name() const override { return "command_clip"; }
  const char* explanation() const override { return "probe: the command clipped to a range"; }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 3; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"lo", -10.0, 10.0, -5.0, "u-level"}, {"hi", -10.0, 10.0, 5.0, "u-level"}};
    return p;
  }
  int numStates() const override { return 0; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    return std::clamp(in, std::min(p[0], p[1]), std::max(p[0], p[1]));
  }
};

// The command's gain changes from 1 to `gain` at the knee (two straight lines, continuous).
class PiecewiseGain final : public Effect {
 public:
  const char* name() const override { return "piecewise_gain"; }
  const char* explanation() const override { return "probe: the command's gain changes at a knee"; }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 4; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"knee", -10.0, 10.0, 0.0, "u-level"}, {"gain", 0.05, 5.0, 1.0, "-"}};
    return p;
  }
  int numStates() const override { return 0; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double*, double, const StepContext&) const noexcept override {}
  double step(const double* p, double*, double in, const StepContext&) const noexcept override {
    return in > p[0] ? p[0] + p[1] * (in - p[0]) : in;
  }
};

// Play of `width` between the muscle and the sensor: the reading moves only once the play is taken up.
class Backlash final : public Effect {
 public:
  const char* name() const override { return "backlash"; }
  const char* explanation() const override { return "probe: play between the displacement and its reading"; }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 98; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"width", 0.0, 5.0, 0.2, "y-unit"}};
    return p;
  }
  int numStates() const override { return 1; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override { s[0] = in0; }
  double step(const double* p, double* s, double in, const StepContext&) const noexcept override {
    const double h = 0.5 * std::fabs(p[0]);
    s[0] = std::clamp(s[0], in - h, in + h);
    return s[0];
  }
};

}  // namespace
std::unique_ptr<Effect> make_dead_zone() { return std::make_unique<DeadZone>(); }
std::unique_ptr<Effect> make_command_clip() { return std::make_unique<CommandClip>(); }
std::unique_ptr<Effect> make_piecewise_gain() { return std::make_unique<PiecewiseGain>(); }
std::unique_ptr<Effect> make_backlash() { return std::make_unique<Backlash>(); }
}  // namespace pamc::model
