#include "model/model.hpp"

#include <algorithm>
#include <cstring>
#include <stdexcept>

namespace pamc::model {

const char* outputFormName(OutputForm f) noexcept { return f == OutputForm::Aligned ? "aligned" : "printed"; }

bool parseOutputForm(const std::string& name, OutputForm& out) noexcept {
  if (name == "aligned")
    out = OutputForm::Aligned;
  else if (name == "printed")
    out = OutputForm::Printed;
  else
    return false;
  return true;
}

Model::Model(const Model& o) : core_(o.core_), form_(o.form_), range_(o.range_), eff_params_(o.eff_params_) {
  for (const auto& s : o.effects_) {
    effects_.push_back(Slot{makeEffect(s.impl->name()), s.param_offset, s.state_offset});
  }
  n_input_ = o.n_input_;
  in_params_ = o.in_params_;
  out_state_begin_ = o.out_state_begin_;
  out_state_end_ = o.out_state_end_;
  n_filter_ = o.n_filter_;
  filter_index_ = o.filter_index_;
}

Model& Model::operator=(const Model& o) {
  if (this != &o) {
    Model tmp(o);
    *this = std::move(tmp);
  }
  return *this;
}

namespace {
// `a` holds `b` as a special case (Effect::refines).
bool refinesEffect(const Effect& a, const std::string& b) {
  const auto r = a.refines();
  return std::find(r.begin(), r.end(), b) != r.end();
}
}  // namespace

void Model::addEffect(const std::string& name) {
  if (hasEffect(name)) throw std::invalid_argument("effect '" + name + "' is already in the model");
  auto e = makeEffect(name);
  // Checked before anything changes, so a refused effect leaves the model as it was.
  int filter_states = e->stage() == Stage::Output ? e->numFilterStates() : 0;
  for (const auto& s : effects_) {
    const char* mine = e->alternativeTo();
    const char* theirs = s.impl->alternativeTo();
    if ((mine && s.impl->name() == std::string(mine)) || (theirs && name == theirs) ||
        refinesEffect(*e, s.impl->name()) || refinesEffect(*s.impl, name))
      throw std::invalid_argument("effects '" + std::string(s.impl->name()) + "' and '" + name +
                                  "' are alternatives for the same physics; a model takes one of them");
    if (s.impl->stage() == Stage::Output) filter_states += s.impl->numFilterStates();
  }
  if (filter_states > kMaxFilterStates)
    throw std::invalid_argument("effect '" + name + "' would give the model " + std::to_string(filter_states) +
                                " output states for the estimator to carry (at most " +
                                std::to_string(kMaxFilterStates) + ")");
  // Keep existing parameter values by name while re-laying out.
  std::vector<std::vector<double>> old;
  for (size_t i = 0; i < effects_.size(); ++i) {
    const auto& ps = effects_[i].impl->params();
    old.emplace_back(eff_params_.begin() + effects_[i].param_offset,
                     eff_params_.begin() + effects_[i].param_offset + static_cast<long>(ps.size()));
  }
  std::vector<double> defs;
  for (const auto& p : e->params()) defs.push_back(p.def);
  effects_.push_back(Slot{std::move(e), 0, 0});
  old.push_back(defs);
  // Stable order: input stage first, then by rank.
  std::vector<size_t> idx(effects_.size());
  for (size_t i = 0; i < idx.size(); ++i) idx[i] = i;
  std::stable_sort(idx.begin(), idx.end(), [&](size_t a, size_t b) {
    const auto& ea = *effects_[a].impl;
    const auto& eb = *effects_[b].impl;
    const int sa = ea.stage() == Stage::Input ? 0 : 1;
    const int sb = eb.stage() == Stage::Input ? 0 : 1;
    if (sa != sb) return sa < sb;
    return ea.rank() < eb.rank();
  });
  std::vector<Slot> sorted;
  eff_params_.clear();
  for (size_t i : idx) {
    sorted.push_back(std::move(effects_[i]));
    sorted.back().param_offset = static_cast<int>(eff_params_.size());
    eff_params_.insert(eff_params_.end(), old[i].begin(), old[i].end());
  }
  effects_ = std::move(sorted);
  relayout();
}

void Model::relayout() {
  int off = 0;
  n_input_ = 0;
  in_params_ = 0;
  out_state_begin_ = -1;
  n_filter_ = 0;
  for (auto& s : effects_) {
    if (s.impl->stage() == Stage::Input) {
      ++n_input_;
      in_params_ += static_cast<int>(s.impl->params().size());
    }
    if (s.impl->stage() == Stage::Output && out_state_begin_ < 0) out_state_begin_ = off;
    s.state_offset = off;
    const int n = s.impl->numStates();
    if (n > kMaxEffectStates) throw std::logic_error(std::string("effect ") + s.impl->name() + " has too many states");
    const int nf = s.impl->numFilterStates();
    if (nf < 0 || nf > n)
      throw std::logic_error(std::string("effect ") + s.impl->name() + " has a bad filter-state count");
    if (s.impl->stage() == Stage::Output) {
      if (n_filter_ + nf > kMaxFilterStates)
        throw std::logic_error("more than " + std::to_string(kMaxFilterStates) + " filter states in one model");
      for (int j = 0; j < nf; ++j) filter_index_[static_cast<size_t>(n_filter_++)] = off + j;
    }
    off += n;
  }
  if (off > kMaxModelStates) throw std::invalid_argument("too many effect states in one model");
  if (out_state_begin_ < 0) out_state_begin_ = off;
  out_state_end_ = off;
}

void Model::setEffectParam(const std::string& effect, const std::string& param, double value) {
  for (const auto& s : effects_) {
    if (effect != s.impl->name()) continue;
    const auto& ps = s.impl->params();
    for (size_t j = 0; j < ps.size(); ++j) {
      if (ps[j].name == param) {
        eff_params_[static_cast<size_t>(s.param_offset) + j] = value;
        return;
      }
    }
    std::string known;
    for (const auto& p : ps) known += (known.empty() ? "" : ", ") + p.name;
    throw std::invalid_argument("effect '" + effect + "' has no parameter '" + param + "' (it has: " + known + ")");
  }
  throw std::invalid_argument("effect '" + effect + "' is not in the model");
}

const double* Model::effectParams(int i) const {
  return eff_params_.data() + effects_[static_cast<size_t>(i)].param_offset;
}

std::vector<std::string> Model::effectNames() const {
  std::vector<std::string> n;
  for (const auto& s : effects_) n.emplace_back(s.impl->name());
  return n;
}

bool Model::hasEffect(const std::string& name) const {
  for (const auto& s : effects_)
    if (name == s.impl->name()) return true;
  return false;
}

bool Model::needsLoad() const {
  for (const auto& s : effects_)
    if (s.impl->needsLoad()) return true;
  return false;
}

std::vector<ParamSpec> Model::paramSpecs() const {
  std::vector<ParamSpec> v = {
      {"k", 0.01, 50.0, 5.0, "mm/V"}, {"rho", 0.0, 2.0, 0.8, "-"},     {"b", -100.0, 100.0, 20.0, "mm"},
      {"alpha", 1.0, 1.0, 1.0, "-"},  {"beta", -3.0, 3.0, 0.3, "1/V"}, {"gamma", -3.0, 3.0, 0.3, "1/V"},
  };
  for (const auto& s : effects_) {
    for (const auto& p : s.impl->params()) {
      ParamSpec q = p;  // unit kept: identification scales the bounds with it
      q.name = std::string(s.impl->name()) + "." + p.name;
      v.push_back(q);
    }
  }
  return v;
}

std::vector<double> Model::params() const {
  std::vector<double> v = {core_.k, core_.rho, core_.b, core_.alpha, core_.beta, core_.gamma};
  v.insert(v.end(), eff_params_.begin(), eff_params_.end());
  return v;
}

void Model::setParams(const std::vector<double>& p) {
  if (static_cast<int>(p.size()) != numParams())
    throw std::invalid_argument("parameter vector has " + std::to_string(p.size()) + " entries, model needs " +
                                std::to_string(numParams()));
  core_ = BoucWenParams{p[0], p[1], p[2], p[3], p[4], p[5]};
  std::copy(p.begin() + kBoucWenParams, p.end(), eff_params_.begin());
}

void Model::init(State& st, double u0, const StepContext& c) const noexcept {
  st.h = 0.0;
  st.u_eff_prev = initInput(st, u0, c);
  initOutput(st, st.u_eff_prev, c);
}

double Model::initInput(State& st, double u0, const StepContext& c) const noexcept {
  double x = u0;
  for (int i = 0; i < n_input_; ++i) {
    const auto& s = effects_[static_cast<size_t>(i)];
    s.impl->init(eff_params_.data() + s.param_offset, st.s.data() + s.state_offset, x, c);
    double tmp[kMaxEffectStates];
    std::memcpy(tmp, st.s.data() + s.state_offset, sizeof(double) * static_cast<size_t>(s.impl->numStates()));
    x = s.impl->step(eff_params_.data() + s.param_offset, tmp, x, c);
  }
  return x;
}

void Model::initOutput(State& st, double x, const StepContext& c) const noexcept {
  StepContext co = c;
  co.u_eff = x;
  double y = coreOutput(x, 0.0);
  for (size_t i = static_cast<size_t>(n_input_); i < effects_.size(); ++i) {
    const auto& s = effects_[i];
    s.impl->init(eff_params_.data() + s.param_offset, st.s.data() + s.state_offset, y, co);
    double tmp[kMaxEffectStates];
    std::memcpy(tmp, st.s.data() + s.state_offset, sizeof(double) * static_cast<size_t>(s.impl->numStates()));
    y = s.impl->step(eff_params_.data() + s.param_offset, tmp, y, co);
  }
}

double Model::inputChain(State& st, double u, const StepContext& c) const noexcept {
  for (int i = 0; i < n_input_; ++i) {
    const auto& s = effects_[static_cast<size_t>(i)];
    u = s.impl->step(eff_params_.data() + s.param_offset, st.s.data() + s.state_offset, u, c);
  }
  return u;
}

double Model::outputChain(State& st, double y, const StepContext& c) const noexcept {
  for (size_t i = static_cast<size_t>(n_input_); i < effects_.size(); ++i) {
    const auto& s = effects_[i];
    y = s.impl->step(eff_params_.data() + s.param_offset, st.s.data() + s.state_offset, y, c);
  }
  return y;
}

double Model::outputPeekChain(const State& st, double y, const StepContext& c) const noexcept {
  double tmp[kMaxModelStates];
  const int n = out_state_end_ - out_state_begin_;
  std::memcpy(tmp, st.s.data() + out_state_begin_, sizeof(double) * static_cast<size_t>(n));
  for (size_t i = static_cast<size_t>(n_input_); i < effects_.size(); ++i) {
    const auto& s = effects_[i];
    y = s.impl->step(eff_params_.data() + s.param_offset, tmp + (s.state_offset - out_state_begin_), y, c);
  }
  return y;
}

double Model::outputWith(const State& st, const double* xf, double* xf_next, double y,
                         const StepContext& c) const noexcept {
  if (!hasOutputEffects()) return y;
  double tmp[kMaxModelStates];
  const int n = out_state_end_ - out_state_begin_;
  std::memcpy(tmp, st.s.data() + out_state_begin_, sizeof(double) * static_cast<size_t>(n));
  for (int i = 0; i < n_filter_; ++i) tmp[filter_index_[static_cast<size_t>(i)] - out_state_begin_] = xf[i];
  for (size_t i = static_cast<size_t>(n_input_); i < effects_.size(); ++i) {
    const auto& s = effects_[i];
    y = s.impl->step(eff_params_.data() + s.param_offset, tmp + (s.state_offset - out_state_begin_), y, c);
  }
  if (xf_next)
    for (int i = 0; i < n_filter_; ++i) xf_next[i] = tmp[filter_index_[static_cast<size_t>(i)] - out_state_begin_];
  return y;
}

void Model::copyOutputStates(const State& from, State& to) const noexcept {
  std::memcpy(to.s.data() + out_state_begin_, from.s.data() + out_state_begin_,
              sizeof(double) * static_cast<size_t>(out_state_end_ - out_state_begin_));
}

double Model::step(State& st, double u, const StepContext& c0, double f_h) const noexcept {
  StepContext c = c0;
  const double ue = inputStage(st, u, c);
  c.u_eff = ue;
  if (aligned()) {
    st.h = boucWenNext(core_, st.h, ue - st.u_eff_prev, f_h, c.Ts);
    st.u_eff_prev = ue;
    return outputStage(st, coreOutput(ue, st.h), c);
  }
  const double y = outputStage(st, coreOutput(ue, st.h), c);
  st.h = boucWenNext(core_, st.h, ue - st.u_eff_prev, f_h, c.Ts);
  st.u_eff_prev = ue;
  return y;
}

void Model::simulate(const double* u, const double* load, size_t n, double Ts, double* y) const noexcept {
  if (n == 0) return;
  State st;
  StepContext c;
  c.Ts = Ts;
  c.load = load ? load[0] : 0.0;
  init(st, u[0], c);
  // Without a load the context is not written in the loop: step() reads it whole, and a packet load of
  // a field just stored waits for the store to retire (a fifth of a fit's time).
  if (load) {
    for (size_t i = 0; i < n; ++i) {
      c.load = load[i];
      y[i] = step(st, u[i], c);
    }
  } else {
    for (size_t i = 0; i < n; ++i) y[i] = step(st, u[i], c);
  }
}

// The stages of simulate(): the same calls with the same arguments, a stage at a time (step() gives
// the input effects the context without u_eff, the output effects the one with it).
double Model::simulateInput(const double* u, const double* load, size_t n, double Ts, double* u_eff) const noexcept {
  if (n == 0) return 0.0;
  State st;
  StepContext c;
  c.Ts = Ts;
  c.load = load ? load[0] : 0.0;
  const double rest = initInput(st, u[0], c);
  for (size_t i = 0; i < n; ++i) {
    if (load) c.load = load[i];  // read by reference here: no copy waits for the store (see simulate())
    u_eff[i] = inputStage(st, u[i], c);
  }
  return rest;
}

void Model::simulateCore(double u_eff_rest, const double* u_eff, size_t n, double Ts, double* y_core) const noexcept {
  double h = 0.0, prev = u_eff_rest;
  if (aligned()) {
    for (size_t i = 0; i < n; ++i) {
      h = boucWenNext(core_, h, u_eff[i] - prev, 0.0, Ts);
      prev = u_eff[i];
      y_core[i] = coreOutput(u_eff[i], h);
    }
    return;
  }
  for (size_t i = 0; i < n; ++i) {
    y_core[i] = coreOutput(u_eff[i], h);
    h = boucWenNext(core_, h, u_eff[i] - prev, 0.0, Ts);
    prev = u_eff[i];
  }
}

void Model::simulateOutput(double u_eff_rest, const double* u_eff, const double* y_core, const double* load, size_t n,
                           double Ts, double* y_out) const noexcept {
  if (n == 0) return;
  if (!hasOutputEffects()) {
    if (y_out != y_core) std::memmove(y_out, y_core, sizeof(double) * n);
    return;
  }
  State st;
  StepContext c;
  c.Ts = Ts;
  c.load = load ? load[0] : 0.0;
  initOutput(st, u_eff_rest, c);
  for (size_t i = 0; i < n; ++i) {
    if (load) c.load = load[i];
    c.u_eff = u_eff[i];
    y_out[i] = outputChain(st, y_core[i], c);
  }
}

std::vector<double> Model::simulate(const std::vector<double>& u, double Ts, const std::vector<double>& load) const {
  std::vector<double> y(u.size());
  simulate(u.data(), load.empty() ? nullptr : load.data(), u.size(), Ts, y.data());
  return y;
}

std::string Model::describe() const {
  std::string d = "bouc_wen";
  for (const auto& s : effects_) d += std::string(" + ") + s.impl->name();
  return d;
}

}  // namespace pamc::model
