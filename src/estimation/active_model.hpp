// Active modelling (paper Section 3): a UKF over the joint state X = [h, f_h] of eqs. (6)-(9),
// where h is the hysteresis state of the model and f_h the modelling error, a random walk.
// The transition and measurement are the shared Model's.
//
// A model with output effects (saturation, a balance, a lag: anything between the core's output and the
// position) takes its modelling error on the position instead where Q_d > 0 (the MBC's; the AMC passes 0), X = [d], y = model + d, h and every effect
// state the model's own, driven by the command (ActiveModelSettings::Q_d; not in the paper). Through such
// an effect the position stops answering h where the effect saturates - a stop, a choked pressure, a
// sticking friction - and an error on h's rate wound h up there, far past the Bouc-Wen's bound, until
// the filter restarted (docs/CONTROL.md, "An estimator for a model with output effects").
//
// With Q_d = 0 such a model keeps the paper's form, and one with lagging output dynamics (mass_spring,
// creep: Model::numFilterStates) has those states in X as well, X = [h, f_h, s]: the measurement of one
// sample hardly depends on that sample's h (through mass_spring by (wn Ts)^2), so the filter must know
// how h reaches y over the following samples, or P_h grows without bound and the gain on h with it. The
// other effect states are propagated alongside with the filter's mean.
#pragma once

#include "estimation/ukf.hpp"
#include "model/model.hpp"

namespace pamc::estimation {

struct ActiveModelSettings {
  UkfSettings ukf{};
  double P0_h = 10.0, P0_f = 10.0;  // eq. (26)
  double Q_h = 10.0, Q_f = 10.0;    // eq. (26)
  double R = 0.001;                 // eq. (26) [mm^2]
  // A model with lagging output dynamics (Model::numFilterStates() > 0; not in the paper) and Q_d = 0. Eq. (26)'s
  // Q = 10 per sample on h and f_h is harmless while each position pins h (the paper's model: y moves
  // with h in the same sample, and R << Q); when h reaches y only over the following samples, Q is what
  // the filter believes h may jump by, and 10 (3 V per millisecond) makes its estimate noisy (up to
  // 7.7 mm off on the emulator's model: OutputDynamics.ThePapersProcessNoiseIsNoisierButStaysBounded)
  // and its command jumpy. Such a model uses these instead of Q_h and Q_f, and carries
  // the output effects' states with this initial spread and random walk (their own units: mm, mm/s).
  double Q_h_lag = 0.1, Q_f_lag = 0.1;
  double P0_out = 1.0, Q_out = 1e-6;
  // A model with output effects: its modelling error on the position, d (y = model + d), a random walk of
  // this initial spread and step [mm^2] (chosen: the middle of 1e-5..1e-3, which all carried the diagnose
  // ladder's models of the calibrated physics plant). 0: the paper's form, or X = [h, f_h, s] with
  // Q_h_lag and Q_f_lag for lagging output dynamics.
  double P0_d = 1.0, Q_d = 1e-4;
  // Divergence guard (not in the paper): a used position that the posterior output misses by more
  // than this [output units] means the filter is lost, whatever its P says; it restarts from the model
  // at rest for the command (status Reset, so the controller goes to its safe state). 0: no guard.
  double diverge = 10.0;
  // Innovation gate (not in the paper): a position whose normalised innovation squared
  // NIS = (y - y_prior)^2 / S exceeds gate_nis is an outlier and is not used (0: no gate). 25 is five
  // standard deviations of the filter's own predicted spread; with eq. (26)'s Q the one-step spread is
  // sqrt(Q_h) |k (1 - rho)| (about 7 mm for the emulator's Bouc-Wen core), so a 40 mm spike is rejected
  // while clean data stays far below the gate (below 1, steps of the setpoint included: docs/RELIABILITY.md,
  // "Bad data in the estimator and controller"). The gate is
  // widened by the model's own predicted change of the output over the sample (S + dy^2: after a
  // command step the model moves at once, the muscle with its lag), and it acts only while the filter
  // is consistent: once 1000 positions have been used since the last reset() and their mean NIS (over
  // about the last 1000) is at most 1. A filter that misses by more than it expects (a model short of
  // the plant's dynamics) cannot tell an outlier from its own miss and would otherwise reject everything.
  double gate_nis = 25.0;
  // At most this many outliers in a row are rejected; the next one is taken as the truth: P back to P0
  // and the position used without the gate (status Reset). A spike this long or shorter is bridged on
  // the model's prediction.
  int gate_max_rejects = 20;
};

struct ActiveModelStep {
  double y_prior = 0.0;  // one-step-ahead prediction of y_k (before y_k is used)
  double y_post = 0.0;   // posterior output estimate (the paper's "with active model")
  double h = 0.0;
  double f_h = 0.0;
  double d = 0.0;  // the modelling error on the position (ActiveModelSettings::Q_d; else 0)
  double nis = 0.0;                  // normalised innovation squared of y_k (0 if y_k was not finite)
  double nis_gate = 0.0;             // what the gate compares with gate_nis: the NIS widened by the model's own step
  bool rejected = false;             // y_k was not used: not finite, or beyond the gate (y_post is the prediction)
  UkfStatus status = UkfStatus::Ok;  // the worse of predict and update (a reset always shows)
};

class ActiveModel {
 public:
  static constexpr int kCore = 2;  // h, f_h
  // The paper's filter for a model without lagging output dynamics; the joint one otherwise (states
  // it does not use are inert). Both fixed-size: nothing is allocated in update().
  using CoreFilter = Ukf<kCore, 1>;
  using Filter = Ukf<kCore + model::kMaxFilterStates, 1>;
  // The filter of a model with output effects (Q_d > 0): d alone, h the model's own.
  using PositionFilter = Ukf<1, 1>;
  static constexpr int kD = kCore;  // d's place in state() and covariance()

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
  // Eq. (17) as printed: the model's output for the nominal command itself, Y_{k+1} = H(h_{k+1}, u_n(k)),
  // not an increment on the posterior. The estimate was fitted with the applied u = u_n + u_c, so the
  // compensation then feeds back on itself through the direct feedthrough with gain kc k rho.
  double predictNextAsPrinted(double u_eff_prev, double u_eff_next, double load) const noexcept;

  // Output `horizon` samples ahead if the command u_hold is applied from the next sample on: the
  // model rolled out from the posterior [h, f_h] and its effect states (lags, delays, inertia).
  double predictAhead(double u_hold, int horizon, double load) const noexcept {
    return predictAhead(nullptr, 0, u_hold, horizon, load);
  }
  // The same with the commands already sent but not yet in effect at the last measurement applied
  // first (in_flight[0] the oldest), then u_hold for the rest of the horizon.
  double predictAhead(const double* in_flight, int n_in_flight, double u_hold, int horizon, double load) const noexcept;

  // The filter in use: its state [h, f_h, filter states...] and covariance (the core filter's
  // embedded in the joint size, with 1 on the diagonal it does not have).
  int filterSize() const noexcept { return kCore + (d_on_ ? 1 : nf_); }
  Filter::Vec state() const noexcept;
  Filter::Mat covariance() const noexcept;
  double gateStatistic() const noexcept {
    return d_on_ ? pos_.gateStatistic() : nf_ > 0 ? ukf_.gateStatistic() : core_.gateStatistic();
  }
  const model::Model::State& modelState() const { return st_; }
  double Ts() const { return Ts_; }
  unsigned resets() const { return resets_; }            // of every kind (P, gate, divergence)
  unsigned divergences() const { return divergences_; }  // restarts by the divergence guard
  unsigned outliers() const { return outliers_total_; }  // positions rejected by the gate since configure()
  double nisLevel() const { return nis_level_; }         // mean NIS of the last ~1000 used positions

 private:
  model::Model model_;
  ActiveModelSettings settings_;
  Filter ukf_;
  model::Model::State st_;
  double Ts_ = 1e-3;
  template <class F>
  typename F::Mat P0() const noexcept;
  template <class F>
  typename F::Mat Q() const noexcept;
  template <class F>
  ActiveModelStep step(F& f, double u, double y, double load) noexcept;
  double h() const noexcept { return d_on_ ? st_.h : nf_ > 0 ? ukf_.x()(0) : core_.x()(0); }
  double fh() const noexcept { return d_on_ ? 0.0 : nf_ > 0 ? ukf_.x()(1) : core_.x()(1); }
  double d() const noexcept { return d_on_ ? pos_.x()(0) : 0.0; }
  CoreFilter core_;
  model::Model::State st_prev_;  // output-effect states of the last sample (filter states: posterior mean)
  double ue_prev_ = 0.0;         // effective command of the last sample
  double load_prev_ = 0.0;
  int nf_ = 0;  // filter states in use (model_.numFilterStates())
  bool d_on_ = false;  // the filter is pos_: the modelling error on the position (ActiveModelSettings::Q_d)
  PositionFilter pos_;
  unsigned divergences_ = 0;
  double y_post_ = 0.0;      // last posterior output
  double du_pending_ = 0.0;  // u_eff(k-1) - u_eff(k-2): drives h_k = F(h_{k-1}) in the printed form
  unsigned resets_ = 0;
  int outlier_run_ = 0;  // outliers in a row
  unsigned outliers_total_ = 0;
  double nis_level_ = 0.0;  // mean NIS of the last ~1000 used positions (the gate acts while <= 1)
  int nis_count_ = 0;       // used positions in that mean (up to 1000)
};

}  // namespace pamc::estimation
