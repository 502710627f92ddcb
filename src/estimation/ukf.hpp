// A generic unscented Kalman filter over fixed-size Eigen types.
//
// The filter knows only the sizes, a transition f(x) and a measurement h(x) passed as callables;
// all physics lives in the model. Standard scaled unscented transform:
//   lambda = a^2 (n + kappa) - n,  Wm0 = lambda / (n + lambda),  Wc0 = Wm0 + 1 - a^2 + b,
//   Wi = 1 / (2 (n + lambda)).
// (The paper's eq. (13) swaps these; its settings a = 1e-3, kappa = 3 - n, b = 2 give
// Wm0 ~ -1e6, so means and covariances are taken about the central sigma point (exactly equal to the
// weighted sums, without the cancellation) and the covariance is guarded:
// symmetrised, checked by Cholesky, repaired by an eigenvalue floor, reset when that fails.)
// update() can gate the measurement on its normalised innovation squared (NIS = nu' S^-1 nu, chi-square
// with M degrees of freedom for a consistent filter): beyond the gate it is not used.
// predict() and update() are noexcept and allocation-free; they return a status, never throw.
// Cost: the step runs at 1 kHz beside the controller, so the small factorisations are written out
// (factor(), the scalar measurement's solves) instead of Eigen's LLT/LDLT, whose dynamic-size
// blocks cost more than the arithmetic at these sizes; each does Eigen's operations in Eigen's order,
// so the results are the same to the bit. The factor guard() computes is kept for the next sigma points;
// a 2 x 2 P that passes a cheaper test implying the factor exists is factored only when sigma points
// need it (surelyDefinite()). The paper's 2-state filter has its own written-out predict
// (predictDriven()) and update (updateLinear()): equal to the generic ones up to rounding, with P
// symmetric as computed, since P's chain from step to step is the step's longest latency.
#pragma once

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>

namespace pamc::estimation {

struct UkfSettings {
  double alpha = 1e-3;  // sigma-point spread (the paper's sigma)
  double beta = 2.0;    // prior-distribution term (the paper's theta); 2 is optimal for Gaussians
  double kappa = -1.0;  // secondary scaling; < -0.5 means "3 - n"
};

enum class UkfStatus : unsigned {
  Ok = 0,
  CovarianceRepaired = 1,   // P lost definiteness and was floored
  Reset = 2,                // P or x became non-finite: x kept if finite, P back to P0
  MeasurementRejected = 3,  // non-finite measurement: the prior is kept
  OutlierRejected = 4,      // innovation beyond the gate: the prior is kept, P held (see update())
};

inline const char* toString(UkfStatus s) {
  switch (s) {
    case UkfStatus::Ok: return "ok";
    case UkfStatus::CovarianceRepaired: return "covariance repaired";
    case UkfStatus::Reset: return "reset";
    case UkfStatus::MeasurementRejected: return "measurement rejected";
    case UkfStatus::OutlierRejected: return "outlier rejected";
  }
  return "?";
}

// Which of two statuses of one step to report: a reset outranks a rejected measurement, which
// outranks a repair (a reset must never be hidden behind the rejection that came with it).
inline int severity(UkfStatus s) noexcept {
  switch (s) {
    case UkfStatus::Ok: return 0;
    case UkfStatus::CovarianceRepaired: return 1;
    case UkfStatus::MeasurementRejected: return 2;
    case UkfStatus::OutlierRejected: return 3;
    case UkfStatus::Reset: return 4;
  }
  return 4;
}
inline UkfStatus worstOf(UkfStatus a, UkfStatus b) noexcept { return severity(a) >= severity(b) ? a : b; }

template <int N, int M>
class Ukf {
 public:
  static constexpr int kSigma = 2 * N + 1;
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  using MVec = Eigen::Matrix<double, M, 1>;
  using MMat = Eigen::Matrix<double, M, M>;
  using Sigmas = Eigen::Matrix<double, N, kSigma>;
  using MSigmas = Eigen::Matrix<double, M, kSigma>;

  explicit Ukf(const UkfSettings& s = UkfSettings{}) { configure(s); }

  void configure(const UkfSettings& s) {
    const double n = N;
    const double kappa = s.kappa < -0.5 ? 3.0 - n : s.kappa;
    lambda_ = s.alpha * s.alpha * (n + kappa) - n;
    gamma_ = std::sqrt(n + lambda_);
    wm0_ = lambda_ / (n + lambda_);
    wi_ = 1.0 / (2.0 * (n + lambda_));
    central_ = s.beta - s.alpha * s.alpha;  // Wc0 - Wm0 - 1 + ... reduces to this (see predict())
    wg_ = wi_ * gamma_;
  }

  void reset(const Vec& x0, const Mat& P0) noexcept {
    x_ = x0;
    setP(P0);
    P0_ = P0;
    P_last_ = P0;
    nis_ = gate_stat_ = 0.0;
  }

  // x <- E[f(x)], P <- Cov[f(x)] + Q. f: Vec (const&) -> Vec.
  template <class F>
  UkfStatus predict(F&& f, const Mat& Q) noexcept {
    UkfStatus st = UkfStatus::Ok;
    Sigmas X, Xp;
    const bool drawn = sigmaPoints(st, X);
    P_last_ = P_;  // as used for the sigma points (repaired if it had to be)
    if (!drawn) return UkfStatus::Reset;
    for (int i = 0; i < kSigma; ++i) Xp.col(i) = f(static_cast<const Vec&>(X.col(i)));
    return predicted(Xp, Q, st);
  }

  // predict() for N = 2 of a state driven by a costly g of itself and a random-walk input that enters
  // linearly: x' = [lim(g(x_0) + b x_1), x_1], lim the clamp to +-limit (NaN passes) - the paper's
  // joint [h, f_h], eq. (9). With P's lower factor L, the sigma points are x +- gamma L.col(j): the
  // pair of L.col(1) has x_0 itself, so g runs on 3 points, and where no point reaches the clamp the
  // pair's share of the sums is known in closed form (gamma^2 Wi = 1/2, L10^2 + L11^2 = P11):
  //   a_+- = g(x_0 +- gamma L00) - g(x_0),  w = Wi gamma L10,  m = Wi (a_+ + a_-)
  //   x'   = [g(x_0) + b x_1 + m, x_1]
  //   P00' = Wi (a_+^2 + a_-^2) + 2 b w (a_+ - a_-) + b^2 P11 + (b - a^2) m^2 + Q00
  //   P10' = w (a_+ - a_-) + b P11 + Q10,  P11' = P11 + Q11.
  // It needs L00 and L10 only: no second square root, and P11's chain is one addition. A P that must
  // be repaired is factored as for predict(); a point at the clamp takes predict()'s way (cold). Equal
  // to predict() up to rounding, statuses included (tests/unit/test_ukf.cpp). g: double -> double.
  template <class G>
  UkfStatus predictDriven(G&& g, double b, double limit, const Mat& Q) noexcept {
    static_assert(N == 2, "the joint state [x_0, x_1]");
    UkfStatus st = UkfStatus::Ok;
    const bool drawn = definite_ || factorOrRepair(st);  // definite_: factor() would succeed
    P_last_ = P_;
    if (!drawn) return UkfStatus::Reset;
    const double h = x_(0), f = x_(1), p00 = P_(0, 0), p10 = P_(1, 0), p11 = P_(1, 1);
    const double l00 = std::sqrt(p00), l10 = p10 / l00;  // as factor()
    const double o = gamma_ * l00, e = gamma_ * l10;
    const double g0 = g(h), gp = g(h + o), gm = g(h - o);
    const double x0 = g0 + b * f;
    // No point at the clamp: the three computed, and the pair x_0' +- b gamma L11 (L11^2 <= P11).
    const double room = limit - std::fabs(x0), bg = b * gamma_;
    if (!((std::fabs(gp + b * (f + e)) <= limit) & (std::fabs(gm + b * (f - e)) <= limit) & (room >= 0.0) &
          (bg * bg * p11 <= room * room)))
      return drivenByPoints(g, b, limit, Q, st);
    const double ap = gp - g0, am = gm - g0, w = wg_ * l10, dw = w * (ap - am);
    const double m = wi_ * (ap + am);
    x_ = Vec(x0 + m, f);
    const double p00n = ((wi_ * (ap * ap + am * am) + (2.0 * b) * dw) + (b * b * p11 + (central_ * m) * m)) + Q(0, 0);
    const double p10n = (dw + b * p11) + Q(1, 0);
    P_.col(0) = Vec(p00n, p10n);  // whole columns, symmetric as computed (Q symmetric)
    P_.col(1) = Vec(p10n, p11 + Q(1, 1));
    factored_ = definite_ = false;
    return worst(st, guardSymmetric());
  }

 private:
  // predictDriven() by its five sigma points, as predict(): where a point reaches the clamp, or x is
  // not finite.
  template <class G>
  [[gnu::cold, gnu::noinline]] UkfStatus drivenByPoints(G& g, double b, double limit, const Mat& Q,
                                                        UkfStatus st) noexcept {
    Sigmas X, Xp;
    if (!sigmaPoints(st, X)) return UkfStatus::Reset;  // P is definite here: not taken
    for (int i = 0; i < kSigma; ++i) {
      double v = g(X(0, i)) + b * X(1, i);
      if (std::fabs(v) > limit) v = std::copysign(limit, v);
      Xp(0, i) = v;
      Xp(1, i) = X(1, i);
    }
    return predicted(Xp, Q, st);
  }

  // The rest of predict() from the transformed sigma points Xp.
  UkfStatus predicted(const Sigmas& Xp, const Mat& Q, UkfStatus st) noexcept {
    // About the central point: P = sum_i Wi d_i d_i' + (b - a^2) m m', d_i = X_i - X_0, m = x - X_0 -
    // algebraically the weighted sum about the mean, without the ~1e6 weights cancelling. Element by
    // element: Eigen's 2-vector packets here cost more in shuffles than they save.
    double d[kSigma][N], wd[kSigma][N];
    for (int i = 1; i < kSigma; ++i)
      for (int r = 0; r < N; ++r) {
        d[i][r] = Xp(r, i) - Xp(r, 0);
        wd[i][r] = wi_ * d[i][r];
      }
    double m[N];
    for (int r = 0; r < N; ++r) {
      double sum = 0.0;
      for (int i = 1; i < kSigma; ++i) sum += d[i][r];
      x_(r) = Xp(r, 0) + wi_ * sum;
      m[r] = x_(r) - Xp(r, 0);
    }
    Mat P;
    for (int c = 0; c < N; ++c)
      for (int r = 0; r < N; ++r) {
        double sum = 0.0;
        for (int i = 1; i < kSigma; ++i) sum += wd[i][r] * d[i][c];
        P(r, c) = (sum + (central_ * m[r]) * m[c]) + Q(r, c);
      }
    setP(P);
    return worst(st, guard());
  }

 public:
  // Measurement update with z = h(x) + v, v ~ N(0, R). h: Vec (const&) -> MVec.
  // Sigma points are drawn afresh from the predicted (x, P).
  // gate > 0: a measurement whose innovation is beyond the gate, nu' (S + widen)^-1 nu > gate, is an
  // outlier and is not used (OutlierRejected); widen (default 0) is spread the caller knows the
  // filter's S leaves out. x stays the prediction and P goes back to what it was before the last
  // predict(), so that a run of outliers is judged against the same spread as its first sample (with a
  // large Q the predicted spread would otherwise grow so fast that the second sample of a spike got in).
  // The caller decides when a run of outliers is the truth after all (reset(), then update() without
  // the gate). nis() is nu' S^-1 nu either way.
  template <class H>
  UkfStatus update(H&& h, const MVec& z, const MMat& R, double gate = 0.0, const MMat& widen = MMat::Zero()) noexcept {
    UkfStatus st = UkfStatus::Ok;
    Sigmas X;
    if (!sigmaPoints(st, X)) return UkfStatus::Reset;
    for (int i = 0; i < kSigma; ++i) Z_.col(i) = h(static_cast<const Vec&>(X.col(i)));
    z_pred_ = weightedMean(Z_);
    if (!z.allFinite()) return worst(st, UkfStatus::MeasurementRejected);
    MMat S = MMat::Zero();
    Eigen::Matrix<double, N, M> C = Eigen::Matrix<double, N, M>::Zero();
    for (int i = 1; i < kSigma; ++i) {
      const MVec dz = Z_.col(i) - Z_.col(0);
      const Vec dx = X.col(i) - X.col(0);
      S.noalias() += wi_ * dz * dz.transpose();
      C.noalias() += wi_ * dx * dz.transpose();
    }
    const MVec mz = z_pred_ - Z_.col(0);
    const Vec mx = x_ - X.col(0);  // zero: these sigma points are centred on x
    S.noalias() += central_ * mz * mz.transpose();
    C.noalias() += central_ * mx * mz.transpose();
    S += R;
    innovation_ = z - z_pred_;
    Eigen::Matrix<double, N, M> K;
    if constexpr (M == 1) {
      // Eigen's LLT, LDLT and their solves written out for 1 x 1: LLT fails only on S <= 0 (NaN
      // passes), a vector is solved by dividing by l twice, a matrix by multiplying with 1 / l twice;
      // LDLT's pseudo-inverse zeroes a pivot not above the smallest normal number.
      const double s = S(0, 0);
      if (s <= 0.0) return worst(st, hardReset());
      const double l = std::sqrt(s);
      const double nu = innovation_(0);
      nis_ = nu * ((nu / l) / l);
      const double d = s + widen(0, 0);
      gate_stat_ = nu * (std::fabs(d) > std::numeric_limits<double>::min() ? nu / d : 0.0);
      if (gate > 0.0 && !(gate_stat_ <= gate)) return worst(st, holdOutlier());
      const double r = 1.0 / l;
      K = (C * r) * r;
    } else {
      Eigen::LLT<MMat> llt(S);
      if (llt.info() != Eigen::Success) return worst(st, hardReset());
      nis_ = innovation_.dot(llt.solve(innovation_));
      gate_stat_ = innovation_.dot(MMat(S + widen).ldlt().solve(innovation_));
      if (gate > 0.0 && !(gate_stat_ <= gate)) return worst(st, holdOutlier());
      K = llt.solve(C.transpose()).transpose();
    }
    x_ += K * innovation_;
    setP(P_ - K * S * K.transpose());
    return worst(st, guard());
  }

  // update() for one linear measurement z = z0 + Hm x + v. The unscented transform of a linear map is
  // exact, so this is the Kalman update that update() computes with sigma points (equal to rounding),
  // without them: the posterior does not wait for a factor of the predicted P. Statuses, gate and
  // nis() as update().
  UkfStatus updateLinear(const Eigen::Matrix<double, 1, N>& Hm, double z0, double z, double R, double gate = 0.0,
                         double widen = 0.0) noexcept {
    static_assert(M == 1, "one measurement");
    UkfStatus st = UkfStatus::Ok;
    if (!definite_ && !factorOrRepair(st)) return UkfStatus::Reset;  // P positive definite, as for sigma points
    double hx = Hm(0) * x_(0);
    for (int j = 1; j < N; ++j) hx += Hm(j) * x_(j);
    z_pred_(0) = z0 + hx;
    if (!std::isfinite(z)) return worst(st, UkfStatus::MeasurementRejected);
    if constexpr (N == 2) {
      // The same operations as below on two-wide packets (one division for both gains, one for both
      // statistics), and x and P stored whole: two scalar stores read back as one packet stall the load.
      // The paper's H = [k (1 - rho), 0] skips the zero column (the same numbers for a finite P).
      const bool one = Hm(1) == 0.0;
      const Vec C = one ? Vec(P_.col(0) * Hm(0)) : Vec(P_.col(0) * Hm(0) + P_.col(1) * Hm(1));
      const double s = (one ? Hm(0) * C(0) : Hm(0) * C(0) + Hm(1) * C(1)) + R;
      if (s <= 0.0) return worst(st, hardReset());
      const double nu = z - z_pred_(0);
      innovation_(0) = nu;
      const double d = s + widen;
      const Vec q = Vec(nu, nu).cwiseQuotient(Vec(s, d));
      nis_ = nu * q(0);
      gate_stat_ = nu * (std::fabs(d) > std::numeric_limits<double>::min() ? q(1) : 0.0);
      if (gate > 0.0 && !(gate_stat_ <= gate)) return worst(st, holdOutlier());
      const Vec K = C / s, KS = K * s;
      x_ += K * nu;
      // P - (K s) K', symmetric as computed (see predictDriven()).
      const Vec diag = P_.diagonal() - KS.cwiseProduct(K);
      const double p10 = P_(1, 0) - KS(1) * K(0);
      P_.col(0) = Vec(diag(0), p10);
      P_.col(1) = Vec(p10, diag(1));
      factored_ = definite_ = false;
      return worst(st, guardSymmetric());
    } else {
      Vec C;
      for (int r = 0; r < N; ++r) {
        C(r) = P_(r, 0) * Hm(0);
        for (int j = 1; j < N; ++j) C(r) += P_(r, j) * Hm(j);
      }
      double s = Hm(0) * C(0);
      for (int j = 1; j < N; ++j) s += Hm(j) * C(j);
      s += R;
      if (s <= 0.0) return worst(st, hardReset());
      const double nu = z - z_pred_(0);
      innovation_(0) = nu;
      nis_ = nu * (nu / s);
      const double d = s + widen;
      gate_stat_ = nu * (std::fabs(d) > std::numeric_limits<double>::min() ? nu / d : 0.0);
      if (gate > 0.0 && !(gate_stat_ <= gate)) return worst(st, holdOutlier());
      double K[N], KS[N];
      for (int r = 0; r < N; ++r) {
        K[r] = C(r) / s;
        KS[r] = K[r] * s;
      }
      for (int r = 0; r < N; ++r) x_(r) += K[r] * nu;
      for (int c = 0; c < N; ++c)
        for (int r = 0; r < N; ++r) P_(r, c) -= KS[r] * K[c];
    }
    factored_ = definite_ = false;
    return worst(st, guard());
  }

  const Vec& x() const noexcept { return x_; }
  Vec& x() noexcept { return x_; }
  const Mat& P() const noexcept { return P_; }
  // Predicted measurement of the last update (before the measurement was used).
  const MVec& predictedMeasurement() const noexcept { return z_pred_; }
  // Innovation, its NIS and the statistic the gate compares (NIS with widen) of the last update that got
  // that far (also when the gate rejected it).
  const MVec& innovation() const noexcept { return innovation_; }
  double nis() const noexcept { return nis_; }
  double gateStatistic() const noexcept { return gate_stat_; }
  double lambda() const noexcept { return lambda_; }
  double wm0() const noexcept { return wm0_; }
  // Wc0 = Wm0 + 1 - a^2 + b; the steps use its difference to Wm0 (central_), so it is derived here.
  double wc0() const noexcept { return wm0_ + 1.0 + central_; }
  double wi() const noexcept { return wi_; }

 private:
  static UkfStatus worst(UkfStatus a, UkfStatus b) noexcept { return worstOf(a, b); }

  // Mean as central point plus weighted offsets: with Wm0 ~ -1e6 the plain weighted sum
  // would cancel catastrophically.
  template <class S>
  auto weightedMean(const S& X) const noexcept {
    Eigen::Matrix<double, S::RowsAtCompileTime, 1> m = Eigen::Matrix<double, S::RowsAtCompileTime, 1>::Zero();
    for (int i = 1; i < kSigma; ++i) m += X.col(i) - X.col(0);
    return (X.col(0) + wi_ * m).eval();
  }

  // Factors P into spread_ = gamma L, L its lower Cholesky factor, with the operations and order of
  // Eigen's unblocked LLT; false where LLT fails (a pivot <= 0; NaN passes). L is built in a local
  // array and stored once: stored piecewise, spread_ was read back as packets that could not be
  // forwarded from the stores.
  bool factor() noexcept {
    double L[N][N] = {};
    for (int k = 0; k < N; ++k) {
      double x = P_(k, k);
      if (k > 0) {
        double s = L[k][0] * L[k][0];
        for (int j = 1; j < k; ++j) s += L[k][j] * L[k][j];
        x -= s;
      }
      if (x <= 0.0) return false;
      x = std::sqrt(x);
      L[k][k] = x;
      for (int i = k + 1; i < N; ++i) {
        double a = P_(i, k);
        if (k > 0) {
          double s = L[i][0] * L[k][0];
          for (int j = 1; j < k; ++j) s += L[i][j] * L[k][j];
          a -= s;
        }
        L[i][k] = a / x;
      }
    }
    for (int c = 0; c < N; ++c)
      for (int r = 0; r < N; ++r) spread_(r, c) = gamma_ * L[r][c];
    factored_ = true;
    return true;
  }

  // Every change of P goes through here: the kept factor no longer applies.
  void setP(const Mat& P) noexcept {
    P_ = P;
    factored_ = definite_ = false;
  }

  // P factored, repaired or reset if it has to be; false if even P0 is not positive definite.
  bool factorOrRepair(UkfStatus& st) noexcept {
    if (!factored_ && !factor()) {
      st = worst(st, repair());
      if (!factor()) {
        st = worst(st, hardReset());
        if (!factor()) return false;
      }
    }
    return true;
  }

  bool sigmaPoints(UkfStatus& st, Sigmas& X) noexcept {
    if (!factorOrRepair(st)) return false;
    for (int r = 0; r < N; ++r) {
      X(r, 0) = x_(r);
      for (int i = 0; i < N; ++i) {
        X(r, 1 + i) = x_(r) + spread_(r, i);
        X(r, 1 + N + i) = x_(r) - spread_(r, i);
      }
    }
    return true;
  }

  // Symmetric, finite, positive definite - or repaired. The common case (x finite, a 2 x 2 P that
  // surelyDefinite() accepts, which implies P finite) costs a few comparisons; the rest is out of line.
  UkfStatus guard() noexcept {
    if constexpr (N == 2) {
      const double p10 = 0.5 * (P_(1, 0) + P_(0, 1));
      P_.col(0) = Vec(P_(0, 0), p10);  // whole columns, as in updateLinear()
      P_.col(1) = Vec(p10, P_(1, 1));
    }
    return guardSymmetric();
  }
  // guard() for a P that is symmetric already (2 x 2) or is symmetrised here (larger).
  UkfStatus guardSymmetric() noexcept {
    factored_ = false;
    if constexpr (N == 2) {
      // v - v is 0 for a finite v and NaN otherwise: one test for all (as Eigen's allFinite()).
      if ((x_(0) - x_(0) + (x_(1) - x_(1)) == 0.0) & surelyDefinite()) {
        definite_ = true;  // factor() will succeed: it runs when sigma points need it
        return UkfStatus::Ok;
      }
      return guardCold();
    } else {
      for (int c = 0; c < N; ++c)
        for (int r = c + 1; r < N; ++r) P_(r, c) = P_(c, r) = 0.5 * (P_(r, c) + P_(c, r));
      return guardRest();
    }
  }
  [[gnu::cold, gnu::noinline]] UkfStatus guardCold() noexcept { return guardRest(); }
  // guard() after symmetrising: non-finite x or P resets, a P that cannot be factored is repaired.
  UkfStatus guardRest() noexcept {
    double zero = 0.0;
    for (int r = 0; r < N; ++r) {
      zero += x_(r) - x_(r);
      for (int c = 0; c < N; ++c) zero += P_(r, c) - P_(r, c);
    }
    if (!(zero == 0.0)) return hardReset();
    if (factor()) return UkfStatus::Ok;
    return repair();
  }

  // For 2 x 2, a test that implies factor() succeeds on the symmetric P, without its square roots and
  // division: with P00, P11 > 0 and P10^2 < P00 P11 / 4 (the product in the normal range) the second
  // pivot P11 - (P10 / sqrt(P00))^2 stays above 3/4 P11 whatever the rounding. With the linear update
  // P is then factored once a step (for the next sigma points) instead of after predict() as well.
  bool surelyDefinite() const noexcept {
    if constexpr (N == 2) {
      const double q = P_(0, 0) * P_(1, 1);  // in the normal range: P00 and P11 of one sign, not 0
      return (P_(0, 0) > 0.0) & (q >= 4.0 * std::numeric_limits<double>::min()) &
             (q <= std::numeric_limits<double>::max()) & (P_(1, 0) * P_(1, 0) < 0.25 * q);
    } else {
      return false;
    }
  }

  // An outlier: P goes back to before the last predict() (see update()).
  UkfStatus holdOutlier() noexcept {
    setP(P_last_);
    return UkfStatus::OutlierRejected;
  }

  // Floors the eigenvalues of P at a small fraction of its scale. Cold, as hardReset(): out of line,
  // so that the step's own code stays small.
  [[gnu::cold, gnu::noinline]] UkfStatus repair() noexcept {
    Eigen::SelfAdjointEigenSolver<Mat> es(P_);
    if (es.info() != Eigen::Success) return hardReset();
    Vec ev = es.eigenvalues();
    const double scale = std::max(ev.cwiseAbs().maxCoeff(), 1e-12);
    for (int i = 0; i < N; ++i) ev(i) = std::max(ev(i), 1e-9 * scale);
    P_ = es.eigenvectors() * ev.asDiagonal() * es.eigenvectors().transpose();
    setP(0.5 * (P_ + P_.transpose()).eval());
    if (!P_.allFinite()) return hardReset();
    return UkfStatus::CovarianceRepaired;
  }

  [[gnu::cold, gnu::noinline]] UkfStatus hardReset() noexcept {
    if (!x_.allFinite()) x_.setZero();
    setP(P0_);
    return UkfStatus::Reset;
  }

  double lambda_ = 0, gamma_ = 0, wm0_ = 0, wi_ = 0;
  double central_ = 0;  // b - a^2: weight of the mean offset in the covariance about X_0
  double wg_ = 0;       // Wi gamma (predictDriven())
  Vec x_ = Vec::Zero();
  Mat P_ = Mat::Identity();
  Mat P0_ = Mat::Identity();
  Mat P_last_ = Mat::Identity();  // P before the last predict (held on an outlier)
  Mat spread_ = Mat::Zero();      // gamma L, L P's Cholesky factor, while factored_
  bool factored_ = false;
  bool definite_ = false;  // P known positive definite (factor() succeeds), not yet factored
  double nis_ = 0.0, gate_stat_ = 0.0;
  MSigmas Z_ = MSigmas::Zero();
  MVec z_pred_ = MVec::Zero();
  MVec innovation_ = MVec::Zero();
};

}  // namespace pamc::estimation
