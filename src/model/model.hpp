// The one PAM model: the Bouc-Wen reference model plus any physical effects from the catalogue.
//
// Used unchanged by the identification (simulate), the UKF (inputStage / core / outputPeek),
// the AMC compensator's one-step prediction and the plant emulator. Configuration (adding
// effects, setting parameters) may allocate and throw; everything taking a State is
// noexcept and allocation-free.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "model/bouc_wen.hpp"
#include "model/effect.hpp"
#include "model/operating_range.hpp"

namespace pamc::model {

constexpr int kMaxModelStates = 600;
// Output-effect states an estimator can carry in its own state (Effect::numFilterStates; mass_spring's
// two and creep's one fit).
constexpr int kMaxFilterStates = 3;

// Which hysteresis state the output of sample k is formed from (docs/MODEL.md, "The output in step with
// the hysteresis"). Aligned: Y_k from h_k after u_k's increment, so the static term k rho u_k and the
// hysteresis term see the same input, as in the continuous model and in the paper's eq. (17). Printed:
// eq. (6) as printed, Y_k from h_k before u_k's increment: the hysteresis term one sample behind the
// static term (a model error of k (1 - rho) dh at every input step). A model runs in the form it was
// fitted in; model files record it (files without it are read as printed, the form they were fitted in).
enum class OutputForm { Aligned, Printed };
const char* outputFormName(OutputForm f) noexcept;
// "aligned" or "printed"; false for anything else.
bool parseOutputForm(const std::string& name, OutputForm& out) noexcept;

class Model {
 public:
  struct State {
    double h = 0.0;                           // Bouc-Wen hysteresis state [V when alpha = 1]
    double u_eff_prev = 0.0;                  // effective input of the previous sample (for u_delta)
    std::array<double, kMaxModelStates> s{};  // effect states, concatenated
  };

  Model() = default;
  explicit Model(const BoucWenParams& core) : core_(core) {}
  Model(const Model& o);
  Model& operator=(const Model& o);
  Model(Model&&) noexcept = default;
  Model& operator=(Model&&) noexcept = default;

  // Adds an effect from the catalogue with its default parameters (throws on unknown names
  // or a duplicate). Effects are kept in signal-chain order (stage, then rank).
  void addEffect(const std::string& name);
  void setEffectParam(const std::string& effect, const std::string& param, double value);

  const BoucWenParams& core() const { return core_; }
  BoucWenParams& core() { return core_; }
  OutputForm outputForm() const noexcept { return form_; }
  void setOutputForm(OutputForm f) noexcept { form_ = f; }
  bool aligned() const noexcept { return form_ == OutputForm::Aligned; }
  // Where the model was identified (not known for a model built by hand or read from an older file).
  const OperatingRange& range() const noexcept { return range_; }
  void setRange(const OperatingRange& r) noexcept { range_ = r; }

  int numEffects() const { return static_cast<int>(effects_.size()); }
  const Effect& effect(int i) const { return *effects_[static_cast<size_t>(i)].impl; }
  const double* effectParams(int i) const;
  std::vector<std::string> effectNames() const;
  bool hasEffect(const std::string& name) const;
  bool hasInputEffects() const { return n_input_ > 0; }
  bool hasOutputEffects() const { return static_cast<int>(effects_.size()) > n_input_; }
  bool needsLoad() const;

  // Flat parameter vector: k, rho, b, alpha, beta, gamma, then each effect's parameters
  // (named "effect.param").
  std::vector<ParamSpec> paramSpecs() const;
  std::vector<double> params() const;
  void setParams(const std::vector<double>& p);
  int numParams() const { return kBoucWenParams + static_cast<int>(eff_params_.size()); }

  // --- runtime (noexcept, no allocation) ---
  // State at rest under the constant command u0 (and load in c).
  void init(State& st, double u0, const StepContext& c) const noexcept;
  // Runs the input effects on command u, returns the effective input.
  // (The stages are inline so that a model without effects of a stage, the paper's, costs no call.)
  double inputStage(State& st, double u, const StepContext& c) const noexcept {
    return n_input_ > 0 ? inputChain(st, u, c) : u;
  }
  // Core output for effective input and hysteresis state.
  double coreOutput(double u_eff, double h) const noexcept { return boucWenOutput(core_, u_eff, h); }
  // Runs the output effects on y_core, advancing their states.
  double outputStage(State& st, double y_core, const StepContext& c) const noexcept {
    return hasOutputEffects() ? outputChain(st, y_core, c) : y_core;
  }
  // Same without touching st (for sigma points and predictions).
  double outputPeek(const State& st, double y_core, const StepContext& c) const noexcept {
    return hasOutputEffects() ? outputPeekChain(st, y_core, c) : y_core;
  }
  // The output effects' states an estimator carries itself (Effect::numFilterStates of the output
  // effects, in chain order, at most kMaxFilterStates): how many, and where each is in State::s.
  int numFilterStates() const { return n_filter_; }
  int filterStateIndex(int i) const { return filter_index_[static_cast<size_t>(i)]; }
  // outputPeek with the filter states taken from xf (numFilterStates() values) instead of st; the
  // filter states after the sample are written to xf_next when it is not null. st is not touched.
  double outputWith(const State& st, const double* xf, double* xf_next, double y_core,
                    const StepContext& c) const noexcept;
  // Copies the output effects' states (all that outputWith reads of a State) from one State to another.
  void copyOutputStates(const State& from, State& to) const noexcept;
  // One whole sample: returns y_k for command u_k and advances st to k+1. f_h is the
  // modelling-error input of eq. (4) (0 for the reference model). Aligned: h takes u_k's increment
  // (and f_h Ts) first and y_k is formed from it; printed: y_k from h before it.
  double step(State& st, double u, const StepContext& c, double f_h = 0.0) const noexcept;

  // Simulates a whole record from rest at u[0]. `load` may be null.
  void simulate(const double* u, const double* load, size_t n, double Ts, double* y_out) const noexcept;
  // simulate() stage by stage over the whole record, each stage from the one before: the input
  // effects' output u_eff (simulateInput returns u_eff at rest), the core's output y_core, the output
  // effects' output y. The chain is feed-forward, so the three give simulate()'s numbers to the bit;
  // StagedSimulation keeps the first two to rerun only the stages a parameter acts in.
  double simulateInput(const double* u, const double* load, size_t n, double Ts, double* u_eff) const noexcept;
  void simulateCore(double u_eff_rest, const double* u_eff, size_t n, double Ts, double* y_core) const noexcept;
  void simulateOutput(double u_eff_rest, const double* u_eff, const double* y_core, const double* load, size_t n,
                      double Ts, double* y_out) const noexcept;
  // Where the stages' parameters are in params(): the core's [0, kBoucWenParams), the input effects'
  // [kBoucWenParams, inputParamsEnd()), the output effects' from there on.
  int inputParamsEnd() const noexcept { return kBoucWenParams + in_params_; }
  std::vector<double> simulate(const std::vector<double>& u, double Ts, const std::vector<double>& load = {}) const;

  // Human-readable one-line description ("bouc_wen + pressure_lag + creep").
  std::string describe() const;

 private:
  struct Slot {
    std::unique_ptr<Effect> impl;
    int param_offset = 0;  // into eff_params_
    int state_offset = 0;  // into State::s
  };
  void relayout();
  double inputChain(State& st, double u, const StepContext& c) const noexcept;
  double outputChain(State& st, double y, const StepContext& c) const noexcept;
  double outputPeekChain(const State& st, double y, const StepContext& c) const noexcept;
  // The two halves of init(): the input effects at rest under u0 (returns their output), and the output
  // effects at rest under the core's output for u_eff x at h = 0.
  double initInput(State& st, double u0, const StepContext& c) const noexcept;
  void initOutput(State& st, double x, const StepContext& c) const noexcept;

  BoucWenParams core_{};
  OutputForm form_ = OutputForm::Aligned;
  OperatingRange range_{};
  std::vector<Slot> effects_;
  std::vector<double> eff_params_;
  int n_input_ = 0;
  int in_params_ = 0;        // parameters of the input effects (the first in eff_params_)
  int out_state_begin_ = 0;  // first state index of the output effects
  int out_state_end_ = 0;
  int n_filter_ = 0;
  std::array<int, kMaxFilterStates> filter_index_{};
};

}  // namespace pamc::model
