// delay: transport delay between command and measured output (pneumatic lines, valve electronics,
// sensor filtering, bus latency): the muscle responds to the command of d seconds ago.
#include <algorithm>
#include <cmath>

#include "model/effect.hpp"

namespace pamc::model {
namespace {

constexpr int kRing = 256;  // samples of history; the identification bounds d to kRing - 2 samples

class Delay final : public Effect {
 public:
  const char* name() const override { return "delay"; }
  const char* explanation() const override {
    return "pure transport delay: the output responds to the command of d seconds ago";
  }
  Stage stage() const override { return Stage::Input; }
  int rank() const override { return 10; }
  const std::vector<ParamSpec>& params() const override {
    static const std::vector<ParamSpec> p = {{"d", 0.0, 0.25, 0.01, "s"}};
    return p;
  }
  int numStates() const override { return kRing + 3; }  // ring, head, cached whole and fractional delay
  void init(const double* p, double* s, double in0, const StepContext& c) const noexcept override {
    std::fill(s, s + kRing, in0);
    s[kRing] = 0.0;
    const double n = std::min(std::max(p[0], 0.0) / c.Ts, static_cast<double>(kRing - 2));
    s[kRing + 1] = std::floor(n);
    s[kRing + 2] = n - std::floor(n);
  }
  double step(const double*, double* s, double in, const StepContext&) const noexcept override {
    int head = static_cast<int>(s[kRing]) + 1;
    if (head == kRing) head = 0;
    s[head] = in;
    s[kRing] = head;
    // Fractional delay by linear interpolation between the two nearest samples.
    int i = head - static_cast<int>(s[kRing + 1]);
    if (i < 0) i += kRing;
    const int j = i == 0 ? kRing - 1 : i - 1;
    return s[i] + s[kRing + 2] * (s[j] - s[i]);
  }
};

}  // namespace
std::unique_ptr<Effect> make_delay() { return std::make_unique<Delay>(); }
}  // namespace pamc::model
