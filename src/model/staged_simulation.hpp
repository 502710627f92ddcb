// Model::simulate() for the many runs of one structure on one record that a fit makes.
//
// The model's chain is feed-forward (input effects -> core -> output effects), so a run whose
// parameters differ from the last new point only in the core's or the output effects' starts at the
// first stage they act in, from that point's kept stages (its u_eff and its core output).
// Levenberg-Marquardt's Jacobian columns change one parameter each: a column of a core parameter
// skips the input effects, one of an output effect skips the core as well. A run that changes more
// than one parameter (a new point: the start, a trial step) is kept; a run that changes one is not,
// so every column of an iteration finds its point's stages. The same numbers as Model::simulate() to
// the bit (tests/unit/test_model.cpp). One per worker; for offline fits only: it allocates (its stage
// buffers on the first run of a record length, the parameter vector on every run).
#pragma once

#include <cstddef>
#include <vector>

#include "model/model.hpp"

namespace pamc::model {

class StagedSimulation {
 public:
  // y_out = m.simulate(u, load, n, Ts). The record (u, load, n, Ts) must stay alive and unchanged
  // between runs that are to share stages (it is recognised by its address).
  void run(const Model& m, const double* u, const double* load, size_t n, double Ts, double* y_out);
  // Which stages the last run computed: 0 all, 1 from the core, 2 the output effects only.
  int lastStart() const noexcept { return last_start_; }

 private:
  std::vector<double> key_;  // parameters of the kept stages; empty: none kept
  const double* u_ = nullptr;
  const double* load_ = nullptr;
  size_t n_ = 0;
  double Ts_ = 0.0;
  double rest_ = 0.0;  // u_eff at rest, of the kept stages
  OutputForm form_ = OutputForm::Aligned;
  std::vector<double> ue_, yc_;          // kept: u_eff and the core's output
  std::vector<double> ue_tmp_, yc_tmp_;  // a one-parameter run's own
  std::vector<double> p_;
  int last_start_ = 0;
};

}  // namespace pamc::model
