#include "estimation/active_model.hpp"

namespace pamc::estimation {

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
  c.u_eff = st_.u_eff_prev;
  y_post_ = model_.outputPeek(st_, model_.coreOutput(st_.u_eff_prev, st_.h), c);
}

ActiveModelStep ActiveModel::update(double u, double y, double load) noexcept {
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
  UkfStatus s2 = ukf_.update(H, Eigen::Matrix<double, 1, 1>(y), R);
  out.y_prior = ukf_.predictedMeasurement()(0);

  out.h = ukf_.x()(0);
  out.f_h = ukf_.x()(1);
  // Advance the output effects with the posterior core output.
  out.y_post = model_.outputStage(st_, model_.coreOutput(ue, out.h), c);
  y_post_ = out.y_post;
  st_.h = out.h;
  du_pending_ = ue - st_.u_eff_prev;
  st_.u_eff_prev = ue;
  out.status = static_cast<unsigned>(s1) > static_cast<unsigned>(s2) ? s1 : s2;
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
