// Linear dynamics and dead time as probes, on either side of the hysteresis: input_lag1 /
// output_lag1 (first order), input_lag2 / output_lag2 (second order: the mass_spring effect's response
// placed on that side) and dead_time (the delay effect's ring). The second-order and dead-time probes
// run the catalogue effects' own code under the probe's name and place.
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {

std::unique_ptr<Effect> make_mass_spring();
std::unique_ptr<Effect> make_delay();

namespace {

class Lag1 final : public Effect {
 public:
  explicit Lag1(Stage stage) : stage_(stage) {}
  const char* name() const override { return stage_ == Stage::Input ? "input_lag1" : "output_lag1"; }
  const char* explanation() const override {
    return stage_ == Stage::Input ? "probe: first-order lag before the hysteresis"
                                  : "probe: first-order lag after the hysteresis";
  }
  Stage stage() const override { return stage_; }
  int rank() const override { return stage_ == Stage::Input ? 31 : 41; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"tau", 1e-3, 5.0, 0.05, "s"}};
    return p;
  }
  int numStates() const override { return 2; }  // output, cached filter gain
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    s[0] = in0;
    retune(p, s, c);
  }
  bool directional() const override { return true; }
  bool followsInput() const override { return true; }
  void retune(const double* p, double* s, const StepContext& c) const noexcept override {
    s[1] = 1.0 - std::exp(-c.Ts / std::max(p[0], 1e-6));
  }
  double step(const double*, double* s, double in, const StepContext&) const noexcept override {
    s[0] += s[1] * (in - s[0]);
    return s[0];
  }

 private:
  Stage stage_;
};

// A catalogue effect's dynamics under a probe's name, stage and rank.
class Placed final : public Effect {
 public:
  Placed(std::unique_ptr<Effect> impl, const char* name, const char* explanation, Stage stage, int rank)
      : impl_(std::move(impl)), name_(name), explanation_(explanation), stage_(stage), rank_(rank) {}
  const char* name() const override { return name_; }
  const char* explanation() const override { return explanation_; }
  Stage stage() const override { return stage_; }
  int rank() const override { return rank_; }
  const std::vector<ParamSpec>& params() const override { return impl_->params(); }
  int numStates() const override { return impl_->numStates(); }
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    impl_->init(p, s, in0, c);
  }
  bool directional() const override { return impl_->directional(); }
  bool followsInput() const override { return impl_->followsInput(); }
  void retune(const double* p, double* s, const StepContext& c) const noexcept override { impl_->retune(p, s, c); }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    return impl_->step(p, s, in, c);
  }

 private:
  std::unique_ptr<Effect> impl_;
  const char *name_, *explanation_;
  Stage stage_;
  int rank_;
};

}  // namespace

std::unique_ptr<Effect> make_input_lag1() { return std::make_unique<Lag1>(Stage::Input); }
std::unique_ptr<Effect> make_output_lag1() { return std::make_unique<Lag1>(Stage::Output); }
std::unique_ptr<Effect> make_input_lag2() {
  return std::make_unique<Placed>(make_mass_spring(), "input_lag2",
                                  "probe: second-order dynamics before the hysteresis", Stage::Input, 32);
}
std::unique_ptr<Effect> make_output_lag2() {
  return std::make_unique<Placed>(make_mass_spring(), "output_lag2",
                                  "probe: second-order dynamics after the hysteresis", Stage::Output, 42);
}
std::unique_ptr<Effect> make_dead_time() {
  return std::make_unique<Placed>(make_delay(), "dead_time", "probe: the whole response comes a fixed time late",
                                  Stage::Input, 9);
}

}  // namespace pamc::model
