// The direction-dependent version of an effect: "<name>_updown" carries each of the effect's parameters
// twice, "<param>_up" for a rising stage input and "<param>_down" for a falling one (held while the input
// holds; for an effect whose state follows its input, Effect::followsInput, rising is that input above
// the state: filling), over the same states - so a lag can fill faster than it vents. At a change of direction the
// effect's derived values are recomputed for the other set (Effect::retune); its states run on.
#include <cmath>
#include <stdexcept>
#include <string>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

class Directional final : public Effect {
 public:
  explicit Directional(std::unique_ptr<Effect> inner)
      : inner_(std::move(inner)),
        name_(std::string(inner_->name()) + kDirectionalSuffix),
        level_(inner_->followsInput() ? 0 : inner_->numStates()) {
    for (const auto& p : inner_->params()) {
      ParamSpec up = p, down = p;
      up.name += "_up";
      down.name += "_down";
      specs_.push_back(up);
      down_.push_back(down);
    }
    specs_.insert(specs_.end(), down_.begin(), down_.end());
    explanation_ = std::string(inner_->explanation()) + ", with separate parameters rising and falling";
  }
  const char* name() const override { return name_.c_str(); }
  const char* explanation() const override { return explanation_.c_str(); }
  Stage stage() const override { return inner_->stage(); }
  int rank() const override { return inner_->rank(); }
  const std::vector<ParamSpec>& params() const override { return specs_; }
  int numStates() const override { return inner_->numStates() + 2; }  // + last input, direction
  int numFilterStates() const override { return inner_->numFilterStates(); }
  const char* alternativeTo() const override { return inner_->name(); }
  bool needsLoad() const override { return inner_->needsLoad(); }
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    inner_->init(p, s, in0, c);
    s[last()] = in0;
    s[last() + 1] = 1.0;
  }
  double step(const double* p, double* s, double in, const StepContext& c) const noexcept override {
    const double d = in - s[level_];
    const double dir = d > 0.0 ? 1.0 : d < 0.0 ? -1.0 : s[last() + 1];
    const double* set = dir > 0.0 ? p : p + down_.size();
    if (dir != s[last() + 1]) inner_->retune(set, s, c);
    s[last()] = in;
    s[last() + 1] = dir;
    return inner_->step(set, s, in, c);
  }

 private:
  int last() const noexcept { return inner_->numStates(); }
  std::unique_ptr<Effect> inner_;
  std::string name_, explanation_;
  std::vector<ParamSpec> specs_, down_;
  int level_;  // the state the input is compared with: the effect's own level, or the last input
};

}  // namespace

std::unique_ptr<Effect> makeDirectional(std::unique_ptr<Effect> inner) {
  if (!inner->directional())
    throw std::invalid_argument("effect '" + std::string(inner->name()) + "' has no direction-dependent version");
  return std::make_unique<Directional>(std::move(inner));
}

}  // namespace pamc::model
