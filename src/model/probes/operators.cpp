// play_hysteresis: a Prandtl-Ishlinskii operator - a weighted sum of six play operators of the
// effective command, their radii spread evenly up to a fitted largest one (r/6, 2r/6, ..., r: thresholds
// spread over the input's range, as Prandtl-Ishlinskii identification spreads them) - added to the
// displacement: a second hysteresis, of another shape than the Bouc-Wen core's (piecewise-linear
// branches, no smooth knee).
// direction_lag: a first-order lag with one time constant rising and another falling (a muscle that
// fills faster than it vents). valve_flow: orifice flow - the effective command moves towards the
// command at rate * sqrt(|difference|), never past it. periodic: a sinusoid added to the displacement,
// unrelated to the command (a vibration from elsewhere).
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

constexpr int kPlays = 6;

class PlayHysteresis final : public Effect {
 public:
  const char* name() const override { return "play_hysteresis"; }
  const char* explanation() const override {
    return "probe: a Prandtl-Ishlinskii sum of play operators of the command";
  }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 50; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"radius", 0.1, 5.0, 2.0, "u-unit"},  // the largest play's
                                             {"w1", -5.0, 5.0, 0.0, "-"},         {"w2", -5.0, 5.0, 0.0, "-"},
                                             {"w3", -5.0, 5.0, 0.0, "-"},         {"w4", -5.0, 5.0, 0.0, "-"},
                                             {"w5", -5.0, 5.0, 0.0, "-"},         {"w6", -5.0, 5.0, 0.0, "-"}};
    return p;
  }
  int numStates() const override { return kPlays; }
  bool directional() const override { return true; }  // separate parameters rising and falling
  void init(const double*, double* s, double, const StepContext& c) const noexcept override {
    for (int i = 0; i < kPlays; ++i) s[i] = c.u_eff;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double spacing = std::fabs(p[0]) / kPlays;
    double y = in;
    for (int i = 0; i < kPlays; ++i) {
      const double r = spacing * (i + 1);
      s[i] = std::clamp(s[i], c.u_eff - r, c.u_eff + r);
      y += p[i + 1] * (s[i] - c.u_eff);  // the play's lag behind the command: zero on a monotone sweep's start
    }
    return y;
  }
};

class DirectionLag final : public Effect {
 public:
  const char* name() const override { return "direction_lag"; }
  const char* explanation() const override {
    return "probe: a first-order lag with separate rising and falling time constants";
  }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 33; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"tau_up", 1e-3, 5.0, 0.05, "s"}, {"tau_down", 1e-3, 5.0, 0.05, "s"}};
    return p;
  }
  int numStates() const override { return 1; }
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override { s[0] = in0; }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double tau = std::max(std::fabs(in > s[0] ? p[0] : p[1]), 1e-6);
    s[0] += (1.0 - std::exp(-c.Ts / tau)) * (in - s[0]);
    return s[0];
  }
};

class ValveFlow final : public Effect {
 public:
  const char* name() const override { return "valve_flow"; }
  const char* explanation() const override {
    return "probe: the effective command moves at a rate growing with the square root of the difference";
  }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 34; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"rate", 0.1, 200.0, 10.0, "-"}};
    return p;
  }
  int numStates() const override { return 1; }
  bool directional() const override { return true; }  // separate parameters filling and venting
  bool followsInput() const override { return true; }
  void init(const double*, double* s, double in0, const StepContext&) const noexcept override { s[0] = in0; }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    constexpr double kLaminar = 0.01;  // below this difference the flow is linear in it
    const double e = in - s[0];
    const double move = std::fabs(p[0]) * c.Ts * e / std::sqrt(std::fabs(e) + kLaminar);
    s[0] += std::clamp(move, -std::fabs(e), std::fabs(e));
    return s[0];
  }
};

class Periodic final : public Effect {
 public:
  const char* name() const override { return "periodic"; }
  const char* explanation() const override { return "probe: a sinusoid added to the displacement"; }
  Stage stage() const override { return Stage::Output; }
  int rank() const override { return 97; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {
        {"amplitude", 0.0, 2.0, 0.0, "y-unit"}, {"freq", 0.5, 200.0, 10.0, "Hz"}, {"phase", -3.2, 3.2, 0.0, "-"}};
    return p;
  }
  int numStates() const override { return 1; }  // time since the start
  void init(const double*, double* s, double, const StepContext&) const noexcept override { s[0] = 0.0; }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    // At the sample's own time (0 at the first sample), so that a record and its decimation (the
    // screening record) see the same phase: counted from the sample's end, the decimated record's time
    // ran 3 ms ahead at a step of 4, 0.2 rad at 11 Hz.
    const double y = in + p[0] * std::sin(2 * M_PI * p[1] * s[0] + p[2]);
    s[0] += c.Ts;
    return y;
  }
};

}  // namespace
std::unique_ptr<Effect> make_play_hysteresis() { return std::make_unique<PlayHysteresis>(); }
std::unique_ptr<Effect> make_direction_lag() { return std::make_unique<DirectionLag>(); }
std::unique_ptr<Effect> make_valve_flow() { return std::make_unique<ValveFlow>(); }
std::unique_ptr<Effect> make_periodic() { return std::make_unique<Periodic>(); }
}  // namespace pamc::model
