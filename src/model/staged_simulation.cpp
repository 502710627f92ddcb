#include "model/staged_simulation.hpp"

namespace pamc::model {

void StagedSimulation::run(const Model& m, const double* u, const double* load, size_t n, double Ts, double* y_out) {
  p_ = m.params();
  const size_t in_end = static_cast<size_t>(m.inputParamsEnd());
  const bool same =
      key_.size() == p_.size() && u == u_ && load == load_ && n == n_ && Ts == Ts_ && m.outputForm() == form_;
  int changed = 0;
  bool input = !same, core = !same;
  if (same) {
    for (size_t i = 0; i < p_.size(); ++i) {
      if (p_[i] == key_[i]) continue;  // NaN: changed
      ++changed;
      if (i < static_cast<size_t>(kBoucWenParams))
        core = true;
      else if (i < in_end)
        input = true;
    }
  }
  const bool keep = !same || changed > 1;
  if (ue_.size() != n) {
    ue_.resize(n), yc_.resize(n), ue_tmp_.resize(n), yc_tmp_.resize(n);
  }
  const double* ue = ue_.data();
  const double* yc = yc_.data();
  double rest = rest_;
  if (input) {
    double* ue_w = keep ? ue_.data() : ue_tmp_.data();
    rest = m.simulateInput(u, load, n, Ts, ue_w);
    ue = ue_w;
  }
  if (input || core) {
    double* yc_w = keep ? yc_.data() : yc_tmp_.data();
    m.simulateCore(rest, ue, n, Ts, yc_w);
    yc = yc_w;
  }
  m.simulateOutput(rest, ue, yc, load, n, Ts, y_out);
  last_start_ = input ? 0 : core ? 1 : 2;
  if (keep) {
    key_ = p_;
    u_ = u, load_ = load, n_ = n, Ts_ = Ts;
    rest_ = rest;
    form_ = m.outputForm();
  }
}

}  // namespace pamc::model
