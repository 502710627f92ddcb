#include "estimation/active_model.hpp"

#include <cmath>

namespace pamc::estimation {

namespace {
// The filter's NIS level: a mean over about kNisWindow used positions; the gate acts once that many
// have been used since the last reset() and the level is at most 1.
constexpr int kNisWindow = 1000;
}  // namespace

void ActiveModel::configure(const model::Model& m, const ActiveModelSettings& s, double Ts) {
  model_ = m;
  settings_ = s;
  Ts_ = Ts;
  ukf_.configure(s.ukf);
  reset(0.0);
}

void ActiveModel::reset(double u0, double load) noexcept {
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  model_.init(st_, u0, c);
  Filter::Mat P0;
  P0 << settings_.P0_h, 0.0, 0.0, settings_.P0_f;
  ukf_.reset(Filter::Vec(st_.h, 0.0), P0);
  du_pending_ = 0.0;
  outlier_run_ = 0;
  nis_level_ = 0.0;
  nis_count_ = 0;
  c.u_eff = st_.u_eff_prev;
  y_post_ = model_.outputPeek(st_, model_.coreOutput(st_.u_eff_prev, st_.h), c);
}

ActiveModelStep ActiveModel::update(double u, double y, double load) noexcept {
  if (!std::isfinite(u)) u = st_.u_eff_prev;  // a nonsense command must not reach the model's states
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  const model::BoucWenParams& p = model_.core();
  const double Ts = Ts_;
  const double du = du_pending_;

  // Eq. (9): F(X) = [h + (BW(u_delta, h) + f_h) Ts, f_h].
  Filter::Mat Q;
  Q << settings_.Q_h, 0.0, 0.0, settings_.Q_f;
  ActiveModelStep out;
  UkfStatus s1 = ukf_.predict(
      [&](const Filter::Vec& x) {
        return Filter::Vec(model::boucWenNext(p, x(0), du, x(1), Ts), x(1));
      },
      Q);

  const double ue = model_.inputStage(st_, u, c);
  c.u_eff = ue;
  // Eq. (9): H(X) = k rho u + b + k (1 - rho) h, then the output effects (not advanced).
  const auto& mdl = model_;
  const auto& st = st_;
  auto H = [&](const Filter::Vec& x) {
    return Eigen::Matrix<double, 1, 1>(mdl.outputPeek(st, mdl.coreOutput(ue, x(0)), c));
  };
  Eigen::Matrix<double, 1, 1> R;
  R << settings_.R;
  // The gate acts only while the filter is consistent (see ActiveModelSettings::gate_nis), and it is
  // widened by the model's own predicted change of the output over this sample: after a command step
  // the model moves at once and the muscle with its lag, a miss that is the model's, not the sensor's.
  const bool consistent = nis_count_ >= kNisWindow && nis_level_ <= 1.0;
  const double gate = settings_.gate_nis > 0.0 && consistent ? settings_.gate_nis : 0.0;
  const double dy_model = H(ukf_.x())(0) - y_post_;
  Eigen::Matrix<double, 1, 1> widen;
  widen << (std::isfinite(dy_model) ? dy_model * dy_model : 0.0);
  UkfStatus s2 = ukf_.update(H, Eigen::Matrix<double, 1, 1>(y), R, gate, widen);
  out.nis_gate = std::isfinite(y) ? ukf_.gateStatistic() : 0.0;
  // One outlier more than gate_max_rejects in a row is the truth after all (the sensor moved, or the
  // filter is lost): start over from P0 at the prediction and take the position without the gate. The
  // gate then re-learns the filter's level, as after reset(), so the way back is not gated either.
  bool restart = false;
  if (s2 == UkfStatus::OutlierRejected && settings_.gate_max_rejects > 0 && outlier_run_ >= settings_.gate_max_rejects) {
    Filter::Mat P0;
    P0 << settings_.P0_h, 0.0, 0.0, settings_.P0_f;
    ukf_.reset(ukf_.x(), P0);  // x is the prediction: a rejected update leaves it there
    s2 = worstOf(ukf_.update(H, Eigen::Matrix<double, 1, 1>(y), R), UkfStatus::Reset);
    restart = true;
    outlier_run_ = 0;
    nis_count_ = 0;
    nis_level_ = 0.0;
  }
  out.y_prior = ukf_.predictedMeasurement()(0);
  out.rejected = s2 == UkfStatus::MeasurementRejected || s2 == UkfStatus::OutlierRejected;
  out.nis = std::isfinite(y) ? ukf_.nis() : 0.0;
  if (s2 == UkfStatus::OutlierRejected) {
    ++outlier_run_;
    ++outliers_total_;
  } else if ((s2 == UkfStatus::Ok || s2 == UkfStatus::CovarianceRepaired) && !restart) {
    // A position was used (a non-finite one neither counts nor ends the run).
    outlier_run_ = 0;
    if (std::isfinite(out.nis)) {
      if (nis_count_ < kNisWindow) ++nis_count_;
      nis_level_ += (out.nis - nis_level_) / static_cast<double>(nis_count_);  // plain mean until the window is full
    }
  }

  out.h = ukf_.x()(0);
  out.f_h = ukf_.x()(1);
  // Advance the output effects with the posterior core output.
  out.y_post = model_.outputStage(st_, model_.coreOutput(ue, out.h), c);
  y_post_ = out.y_post;
  st_.h = out.h;
  du_pending_ = ue - st_.u_eff_prev;
  st_.u_eff_prev = ue;
  out.status = worstOf(s1, s2);
  if (out.status == UkfStatus::Reset) ++resets_;
  return out;
}

double ActiveModel::predictNext(double u_eff_prev, double u_eff_next, double load) const noexcept {
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  // Eq. (17): h_{k+1} = h_k + [BW(u_n,delta, h_k) + f_h] Ts; Y_{k+1} = k rho u_n(k) + b + k (1 - rho) h_{k+1},
  // taken as an increment on the posterior output: Y_{k+1} = Y_post(k) + H(h_{k+1}, u_n(k)) - H(h_k, u_n(k-1)).
  // Without compensation (u = u_n) this is eq. (17) exactly; with it, the estimate (fitted with the
  // applied u = u_n + u_c) is not compared against u_n through the direct feedthrough k rho, which
  // would feed u_c back onto itself with gain kc k rho and ring when that exceeds 1.
  const double h0 = ukf_.x()(0);
  const double h1 = model::boucWenNext(model_.core(), h0, u_eff_next - u_eff_prev, ukf_.x()(1), Ts_);
  model::StepContext c1 = c;
  c1.u_eff = u_eff_next;
  c.u_eff = u_eff_prev;
  const double y1 = model_.outputPeek(st_, model_.coreOutput(u_eff_next, h1), c1);
  const double y0 = model_.outputPeek(st_, model_.coreOutput(u_eff_prev, h0), c);
  return y_post_ + (y1 - y0);
}

double ActiveModel::predictAhead(const double* in_flight, int n_in_flight, double u_hold, int horizon,
                                 double load) const noexcept {
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  model::Model::State s = st_;
  double h = ukf_.x()(0);
  const double f = ukf_.x()(1);
  double du = du_pending_;
  double y = y_post_;
  for (int i = 0; i < horizon; ++i) {
    h = model::boucWenNext(model_.core(), h, du, f, Ts_);
    const double ue = model_.inputStage(s, i < n_in_flight ? in_flight[i] : u_hold, c);
    c.u_eff = ue;
    y = model_.outputStage(s, model_.coreOutput(ue, h), c);
    du = ue - s.u_eff_prev;
    s.u_eff_prev = ue;
  }
  return y;
}

}  // namespace pamc::estimation
