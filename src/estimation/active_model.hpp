// Active modelling (paper Section 3): a UKF over the joint state X = [h, f_h] of eqs. (6)-(9),
// where h is the hysteresis state of the model and f_h the modelling error, a random walk.
// The transition and measurement are the shared Model's; effect states of the model are
// propagated alongside with the filter's mean.
#pragma once

#include "estimation/ukf.hpp"
#include "model/model.hpp"

namespace pamc::estimation {

struct ActiveModelSettings {
  UkfSettings ukf{};
  double P0_h = 10.0, P0_f = 10.0;  // eq. (26)
  double Q_h = 10.0, Q_f = 10.0;    // eq. (26)
  double R = 0.001;                 // eq. (26) [mm^2]
};

struct ActiveModelStep {
  double y_prior = 0.0;  // one-step-ahead prediction of y_k (before y_k is used)
  double y_post = 0.0;   // posterior output estimate (the paper's "with active model")
  double h = 0.0;
  double f_h = 0.0;
  UkfStatus status = UkfStatus::Ok;
};

class ActiveModel {
 public:
  using Filter = Ukf<2, 1>;

  // May allocate (copies the model).
  void configure(const model::Model& m, const ActiveModelSettings& s, double Ts);
  const model::Model& model() const { return model_; }
  const ActiveModelSettings& settings() const { return settings_; }

  // Rest state for the command u0 (resets the filter to P0).
  void reset(double u0, double load = 0.0) noexcept;

  // One sample: u is the command in effect when y was measured. noexcept, no allocation.
  ActiveModelStep update(double u, double y, double load = 0.0) noexcept;

  // Eq. (17): output one sample ahead if the command u_next follows u_prev, from the
  // current posterior, in effective-input units (after the model's input effects).
  double predictNext(double u_eff_prev, double u_eff_next, double load) const noexcept;

  // Output `horizon` samples ahead if the command u_hold is applied from the next sample on: the
  // model rolled out from the posterior [h, f_h] and its effect states (lags, delays, inertia).
  double predictAhead(double u_hold, int horizon, double load) const noexcept {
    return predictAhead(nullptr, 0, u_hold, horizon, load);
  }
  // The same with the commands already sent but not yet in effect at the last measurement applied
  // first (in_flight[0] the oldest), then u_hold for the rest of the horizon.
  double predictAhead(const double* in_flight, int n_in_flight, double u_hold, int horizon, double load) const noexcept;

  const Filter& filter() const { return ukf_; }
  const model::Model::State& modelState() const { return st_; }
  double Ts() const { return Ts_; }
  unsigned resets() const { return resets_; }

 private:
  model::Model model_;
  ActiveModelSettings settings_;
  Filter ukf_;
  model::Model::State st_;
  double Ts_ = 1e-3;
  double y_post_ = 0.0;      // last posterior output
  double du_pending_ = 0.0;  // u_eff(k-1) - u_eff(k-2): drives h_k = F(h_{k-1})
  unsigned resets_ = 0;
};

}  // namespace pamc::estimation
