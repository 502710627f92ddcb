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
  core_.configure(s.ukf);
  pos_.configure(s.ukf);
  reset(0.0);
}

template <class F>
typename F::Mat ActiveModel::P0() const noexcept {
  typename F::Mat P = F::Mat::Identity();  // unused filter states: inert at 1
  if constexpr (F::Mat::RowsAtCompileTime == 1) {
    P(0, 0) = settings_.P0_d;
  } else {
    P(0, 0) = settings_.P0_h;
    P(1, 1) = settings_.P0_f;
    for (int i = 0; i < nf_ && kCore + i < F::Mat::RowsAtCompileTime; ++i) P(kCore + i, kCore + i) = settings_.P0_out;
  }
  return P;
}

template <class F>
typename F::Mat ActiveModel::Q() const noexcept {
  typename F::Mat Q = F::Mat::Zero();
  if constexpr (F::Mat::RowsAtCompileTime == 1) {
    Q(0, 0) = settings_.Q_d;
  } else {
    Q(0, 0) = nf_ > 0 ? settings_.Q_h_lag : settings_.Q_h;
    Q(1, 1) = nf_ > 0 ? settings_.Q_f_lag : settings_.Q_f;
    for (int i = 0; i < nf_ && kCore + i < F::Mat::RowsAtCompileTime; ++i) Q(kCore + i, kCore + i) = settings_.Q_out;
  }
  return Q;
}

ActiveModel::Filter::Vec ActiveModel::state() const noexcept {
  if (nf_ > 0) return ukf_.x();
  Filter::Vec x = Filter::Vec::Zero();
  if (d_on_) {
    x(0) = st_.h;
    x(kD) = pos_.x()(0);
  } else {
    x.head<kCore>() = core_.x();
  }
  return x;
}

ActiveModel::Filter::Mat ActiveModel::covariance() const noexcept {
  if (nf_ > 0) return ukf_.P();
  Filter::Mat P = Filter::Mat::Identity();
  if (d_on_)
    P(kD, kD) = pos_.P()(0, 0);
  else
    P.topLeftCorner<kCore, kCore>() = core_.P();
  return P;
}

void ActiveModel::reset(double u0, double load) noexcept {
  d_on_ = model_.hasOutputEffects() && settings_.Q_d > 0.0;
  nf_ = d_on_ ? 0 : model_.numFilterStates();
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  model_.init(st_, u0, c);
  Filter::Vec x0 = Filter::Vec::Zero();
  x0(0) = st_.h;
  for (int i = 0; i < nf_; ++i) x0(kCore + i) = st_.s[static_cast<size_t>(model_.filterStateIndex(i))];
  if (d_on_)
    pos_.reset(PositionFilter::Vec::Zero(), P0<PositionFilter>());
  else if (nf_ > 0)
    ukf_.reset(x0, P0<Filter>());
  else
    core_.reset(x0.head<kCore>(), P0<CoreFilter>());
  du_pending_ = 0.0;
  outlier_run_ = 0;
  nis_level_ = 0.0;
  nis_count_ = 0;
  // At rest the output effects stay where they are: the first transition starts from here.
  model_.copyOutputStates(st_, st_prev_);
  ue_prev_ = st_.u_eff_prev;
  load_prev_ = load;
  c.u_eff = st_.u_eff_prev;
  y_post_ = model_.outputPeek(st_, model_.coreOutput(st_.u_eff_prev, st_.h), c);
}

ActiveModelStep ActiveModel::update(double u, double y, double load) noexcept {
  if (d_on_) return step(pos_, u, y, load);
  return nf_ > 0 ? step(ukf_, u, y, load) : step(core_, u, y, load);
}

template <class F>
ActiveModelStep ActiveModel::step(F& ukf, double u, double y, double load) noexcept {
  using Vec = typename F::Vec;
  if (!std::isfinite(u)) u = st_.u_eff_prev;  // a nonsense command must not reach the model's states
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  const model::BoucWenParams& p = model_.core();
  const double Ts = Ts_;
  // The effective command of this sample. Aligned form: its own increment drives h_k, from which y_k
  // is formed; printed form (eq. 6 as printed): the last sample's increment, y_k from h before u_k's.
  const double ue = model_.inputStage(st_, u, c);
  c.u_eff = ue;
  const double du = model_.aligned() ? ue - st_.u_eff_prev : du_pending_;

  // Eq. (9): F(X) = [h + (BW(u_delta, h) + f_h) Ts, f_h], and the filter states s of the output
  // effects advanced by the last sample's output stage, driven by that sample's core output.
  const auto& mdl = model_;
  model::StepContext cp;
  cp.Ts = Ts;
  cp.load = load_prev_;
  cp.u_eff = ue_prev_;
  const int nf = nf_;
  ActiveModelStep out;
  const model::BoucWenStep bw(p, du, h());  // the same increment for every sigma point
  // The position form's h: the model's own, not estimated (ActiveModelSettings::Q_d).
  const double h_model = Vec::RowsAtCompileTime == 1 ? bw(st_.h, 0.0, Ts) : 0.0;
  const double y_model = Vec::RowsAtCompileTime == 1 ? model_.outputPeek(st_, model_.coreOutput(ue, h_model), c) : 0.0;
  UkfStatus s1;
  if constexpr (Vec::RowsAtCompileTime == 1) {
    s1 = ukf.predict([](const Vec& x) { return x; }, Q<F>());  // d' = d, a random walk
  } else if constexpr (Vec::RowsAtCompileTime == kCore) {
    // h' = BW(h) + f_h Ts (clamped as boucWenFinish), f_h' = f_h: the Bouc-Wen part reads h alone and
    // f_h enters linearly (Ukf::predictDriven).
    s1 = ukf.predictDriven([&](double h) { return bw.advance(h); }, Ts, model::detail::kHLimit, Q<F>());
  } else {
    s1 = ukf.predict(
        [&](const Vec& x) {
          Vec n = x;
          n(0) = bw(x(0), x(1), Ts);
          double next[model::kMaxFilterStates];
          mdl.outputWith(st_prev_, x.data() + kCore, next, mdl.coreOutput(ue_prev_, x(0)), cp);
          for (int i = 0; i < nf; ++i) n(kCore + i) = next[i];
          return n;
        },
        Q<F>());
  }

  // Eq. (9): H(X) = k rho u + b + k (1 - rho) h, then the output effects (not advanced), their
  // filter states taken from X.
  const auto& st = st_;
  const bool output_effects = mdl.hasOutputEffects();
  auto H = [&](const Vec& x) {
    if constexpr (Vec::RowsAtCompileTime == 1)  // y = model + d, the output effects on the mean
      return Eigen::Matrix<double, 1, 1>(y_model + x(0));
    else if constexpr (Vec::RowsAtCompileTime > kCore)
      return Eigen::Matrix<double, 1, 1>(mdl.outputWith(st, x.data() + kCore, nullptr, mdl.coreOutput(ue, x(0)), c));
    else if (output_effects)
      return Eigen::Matrix<double, 1, 1>(mdl.outputPeek(st, mdl.coreOutput(ue, x(0)), c));
    else  // the paper's model: what outputPeek returns, without the call per sigma point
      return Eigen::Matrix<double, 1, 1>(mdl.coreOutput(ue, x(0)));
  };
  // The paper's model alone measures y = (k rho u + b) + k (1 - rho) h, linear in X: the Kalman update
  // without sigma points (Ukf::updateLinear).
  auto correct = [&](double gate, double widen) {
    if constexpr (Vec::RowsAtCompileTime == 1)
      return ukf.updateLinear(Eigen::Matrix<double, 1, 1>(1.0), y_model, y, settings_.R, gate, widen);
    if constexpr (Vec::RowsAtCompileTime == kCore) {
      if (!output_effects) {
        const Eigen::Matrix<double, 1, kCore> Hm(p.k * (1.0 - p.rho), 0.0);
        return ukf.updateLinear(Hm, p.k * p.rho * ue + p.b, y, settings_.R, gate, widen);
      }
    }
    return ukf.update(H, Eigen::Matrix<double, 1, 1>(y), Eigen::Matrix<double, 1, 1>(settings_.R), gate,
                      Eigen::Matrix<double, 1, 1>(widen));
  };
  // The gate acts only while the filter is consistent (see ActiveModelSettings::gate_nis), and it is
  // widened by the model's own predicted change of the output over this sample: after a command step
  // the model moves at once and the muscle with its lag, a miss that is the model's, not the sensor's.
  const bool consistent = nis_count_ >= kNisWindow && nis_level_ <= 1.0;
  const double gate = settings_.gate_nis > 0.0 && consistent ? settings_.gate_nis : 0.0;
  const double dy_model = H(ukf.x())(0) - y_post_;
  UkfStatus s2 = correct(gate, std::isfinite(dy_model) ? dy_model * dy_model : 0.0);
  out.nis_gate = std::isfinite(y) ? ukf.gateStatistic() : 0.0;
  // One outlier more than gate_max_rejects in a row is the truth after all (the sensor moved, or the
  // filter is lost): start over from P0 at the prediction and take the position without the gate. The
  // gate then re-learns the filter's level, as after reset(), so the way back is not gated either.
  bool restart = false;
  if (s2 == UkfStatus::OutlierRejected && settings_.gate_max_rejects > 0 &&
      outlier_run_ >= settings_.gate_max_rejects) {
    ukf.reset(ukf.x(), P0<F>());  // x is the prediction: a rejected update leaves it there
    s2 = worstOf(correct(0.0, 0.0), UkfStatus::Reset);
    restart = true;
    outlier_run_ = 0;
    nis_count_ = 0;
    nis_level_ = 0.0;
  }
  out.y_prior = ukf.predictedMeasurement()(0);
  out.rejected = s2 == UkfStatus::MeasurementRejected || s2 == UkfStatus::OutlierRejected;
  out.nis = std::isfinite(y) ? ukf.nis() : 0.0;
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

  if constexpr (Vec::RowsAtCompileTime == 1) {
    out.h = h_model;
    out.f_h = 0.0;
  } else {
    out.h = ukf.x()(0);
    out.f_h = ukf.x()(1);
  }
  // The posterior filter states into the model's state, kept as the start of the next transition;
  // then the output effects advance with the posterior core output.
  if constexpr (Vec::RowsAtCompileTime > kCore) {
    for (int i = 0; i < nf_; ++i) st_.s[static_cast<size_t>(model_.filterStateIndex(i))] = ukf.x()(kCore + i);
    model_.copyOutputStates(st_, st_prev_);  // only the joint filter's transition reads it
  }
  ue_prev_ = ue;
  load_prev_ = load;
  out.d = d();
  out.y_post = model_.outputStage(st_, model_.coreOutput(ue, out.h), c) + out.d;
  y_post_ = out.y_post;
  st_.h = out.h;
  du_pending_ = ue - st_.u_eff_prev;
  st_.u_eff_prev = ue;
  out.status = worstOf(s1, s2);
  // Divergence guard: a used position the posterior misses by more than `diverge` - the filter is
  // lost whatever its P says. Start over from the model at rest for this command, and say so.
  const bool used = s2 == UkfStatus::Ok || s2 == UkfStatus::CovarianceRepaired || restart;
  if (settings_.diverge > 0.0 && used && std::isfinite(y) && !(std::fabs(y - out.y_post) <= settings_.diverge)) {
    reset(u, load);
    ++divergences_;
    out.h = h();
    out.f_h = fh();
    out.y_post = y_post_;
    out.status = UkfStatus::Reset;
  }
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
  // applied u = u_n + u_c) is not compared against u_n through the direct feedthrough k rho, as the
  // printed form (predictNextAsPrinted) does, feeding u_c back onto itself with gain kc k rho.
  c.u_eff = u_eff_prev;
  const double y0 = model_.outputPeek(st_, model_.coreOutput(u_eff_prev, h()), c) + d();
  return y_post_ + (predictNextAsPrinted(u_eff_prev, u_eff_next, load) - y0);
}

double ActiveModel::predictNextAsPrinted(double u_eff_prev, double u_eff_next, double load) const noexcept {
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  c.u_eff = u_eff_next;
  const double h1 = model::boucWenNext(model_.core(), h(), u_eff_next - u_eff_prev, fh(), Ts_);
  return model_.outputPeek(st_, model_.coreOutput(u_eff_next, h1), c) + d();
}

double ActiveModel::predictAhead(const double* in_flight, int n_in_flight, double u_hold, int horizon,
                                 double load) const noexcept {
  model::StepContext c;
  c.Ts = Ts_;
  c.load = load;
  model::Model::State s = st_;
  double h = this->h();
  const double f = fh();
  const bool aligned = model_.aligned();
  double du = du_pending_;
  double y = y_post_;
  for (int i = 0; i < horizon; ++i) {
    if (!aligned) h = model::boucWenNext(model_.core(), h, du, f, Ts_);
    const double ue = model_.inputStage(s, i < n_in_flight ? in_flight[i] : u_hold, c);
    c.u_eff = ue;
    du = ue - s.u_eff_prev;
    s.u_eff_prev = ue;
    if (aligned) h = model::boucWenNext(model_.core(), h, du, f, Ts_);
    y = model_.outputStage(s, model_.coreOutput(ue, h), c) + d();
  }
  return y;
}

}  // namespace pamc::estimation
