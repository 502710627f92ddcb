#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "estimation/ukf.hpp"

using pamc::estimation::Ukf;
using pamc::estimation::UkfSettings;
using pamc::estimation::UkfStatus;

// One predict/update step worked out by hand (a = 1, b = 0, kappa = 2, n = 1):
// lambda = 2, n + lambda = 3, Wm0 = Wc0 = 2/3, Wi = 1/6; sigma points 1, 1 +- sqrt(3).
// f(x) = x^2: mean = 2/3 + (8)/6 = 2, P = 2/3*1 + 1/6*((2+2sqrt3)^2 + (2-2sqrt3)^2) = 6, + Q 0.5 = 6.5.
// h(x) = x, z = 3, R = 0.5: S = 7, C = 6.5, K = 13/14, x = 2 + 13/14 = 41/14, P = 6.5 - 6.5^2/7 = 13/28.
TEST(Ukf, OneStepByHand) {
  UkfSettings s;
  s.alpha = 1.0;
  s.beta = 0.0;
  s.kappa = 2.0;
  Ukf<1, 1> f(s);
  EXPECT_DOUBLE_EQ(f.lambda(), 2.0);
  EXPECT_DOUBLE_EQ(f.wm0(), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(f.wc0(), 2.0 / 3.0);
  EXPECT_DOUBLE_EQ(f.wi(), 1.0 / 6.0);
  f.reset(Ukf<1, 1>::Vec(1.0), Ukf<1, 1>::Mat(1.0));
  auto st = f.predict([](const Ukf<1, 1>::Vec& x) { return Ukf<1, 1>::Vec(x(0) * x(0)); }, Ukf<1, 1>::Mat(0.5));
  EXPECT_EQ(st, UkfStatus::Ok);
  EXPECT_NEAR(f.x()(0), 2.0, 1e-12);
  EXPECT_NEAR(f.P()(0, 0), 6.5, 1e-12);
  st = f.update([](const Ukf<1, 1>::Vec& x) { return Ukf<1, 1>::MVec(x(0)); }, Ukf<1, 1>::MVec(3.0),
                Ukf<1, 1>::MMat(0.5));
  EXPECT_EQ(st, UkfStatus::Ok);
  EXPECT_NEAR(f.predictedMeasurement()(0), 2.0, 1e-12);
  EXPECT_NEAR(f.x()(0), 41.0 / 14.0, 1e-12);
  EXPECT_NEAR(f.P()(0, 0), 13.0 / 28.0, 1e-12);
}

// The paper's settings give Wm0 of about -1e6; on a linear system the UKF must still equal the
// Kalman filter.
TEST(Ukf, PaperSettingsMatchKalmanOnLinearSystem) {
  Ukf<2, 1> f;  // a = 1e-3, b = 2, kappa = 3 - n
  EXPECT_NEAR(f.wm0(), (1e-6 * 3 - 2) / (1e-6 * 3), 1e-3);
  EXPECT_LT(f.wm0(), -6e5);
  EXPECT_NEAR(f.wm0() + 4 * f.wi(), 1.0, 1e-9);
  using V = Ukf<2, 1>::Vec;
  using M = Ukf<2, 1>::Mat;
  M A;
  A << 1.0, 0.01, 0.0, 1.0;
  M Q = M::Identity() * 0.1;
  Eigen::Matrix<double, 1, 2> H(1.0, 0.5);
  Eigen::Matrix<double, 1, 1> R(0.2);
  V x(1.0, -2.0);
  M P;
  P << 2.0, 0.3, 0.3, 1.0;
  f.reset(x, P);
  for (int k = 0; k < 50; ++k) {
    const double z = std::sin(0.1 * k);
    ASSERT_EQ(f.predict([&](const V& s) { return V(A * s); }, Q), UkfStatus::Ok);
    x = A * x;
    P = A * P * A.transpose() + Q;
    ASSERT_EQ(f.update([&](const V& s) { return Ukf<2, 1>::MVec(H * s); }, Ukf<2, 1>::MVec(z), R), UkfStatus::Ok);
    const Eigen::Matrix<double, 1, 1> S = H * P * H.transpose() + R;
    const Eigen::Matrix<double, 2, 1> K = P * H.transpose() / S(0);
    x = x + K * (z - (H * x)(0));
    P = P - K * S * K.transpose();
    EXPECT_NEAR((f.x() - x).norm(), 0.0, 1e-6 * (1 + x.norm()));
    EXPECT_NEAR((f.P() - P).norm(), 0.0, 1e-6 * (1 + P.norm()));
  }
}

TEST(Ukf, IndefiniteCovarianceIsRepairedNotFatal) {
  Ukf<2, 1> f;
  Ukf<2, 1>::Mat bad;
  bad << 1.0, 2.0, 2.0, 1.0;  // eigenvalues 3 and -1
  f.reset(Ukf<2, 1>::Vec(0, 0), bad);
  const auto st = f.predict([](const Ukf<2, 1>::Vec& x) { return x; }, Ukf<2, 1>::Mat::Identity() * 1e-3);
  EXPECT_EQ(st, UkfStatus::CovarianceRepaired);
  Eigen::LLT<Ukf<2, 1>::Mat> llt(f.P());
  EXPECT_EQ(llt.info(), Eigen::Success);
  EXPECT_TRUE(f.P().isApprox(f.P().transpose()));
}

TEST(Ukf, NonFiniteStateResetsAndNonFiniteMeasurementIsRejected) {
  Ukf<2, 1> f;
  const Ukf<2, 1>::Mat P0 = Ukf<2, 1>::Mat::Identity() * 10;
  f.reset(Ukf<2, 1>::Vec(1, 1), P0);
  auto st = f.predict([](const Ukf<2, 1>::Vec&) { return Ukf<2, 1>::Vec(NAN, 0); }, P0);
  EXPECT_EQ(st, UkfStatus::Reset);
  EXPECT_TRUE(f.x().allFinite());
  EXPECT_TRUE(f.P().isApprox(P0));
  st = f.update([](const Ukf<2, 1>::Vec& x) { return Ukf<2, 1>::MVec(x(0)); }, Ukf<2, 1>::MVec(NAN),
                Ukf<2, 1>::MMat(1e-3));
  EXPECT_EQ(st, UkfStatus::MeasurementRejected);
  EXPECT_TRUE(f.x().allFinite());
}

// updateLinear is update() for a linear measurement without sigma points: on a random walk of
// states, covariances and measurements both give the same posterior, NIS, gate decision and status.
TEST(Ukf, LinearUpdateEqualsTheSigmaPointUpdate) {
  using F = Ukf<2, 1>;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  for (int k = 0; k < 300; ++k) {
    F a, b;
    F::Vec x(U(rng), 2.0 * U(rng));
    const double c = 0.9 * U(rng), s0 = 0.1 + std::fabs(U(rng)), s1 = 0.1 + 5.0 * std::fabs(U(rng));
    F::Mat P;
    P << s0 * s0, c * s0 * s1, c * s0 * s1, s1 * s1;
    a.reset(x, P);
    b.reset(x, P);
    const Eigen::Matrix<double, 1, 2> H(5.0 * U(rng), (k % 2) * U(rng));  // half with a zero: the paper's form
    const double z0 = U(rng), R = 1e-3 + std::fabs(U(rng)) * 0.1;
    const double z = z0 + H * x + 3.0 * U(rng), gate = k % 4 == 0 ? 4.0 : 0.0, widen = k % 5 == 0 ? 0.5 : 0.0;
    const auto sa =
        a.update([&](const F::Vec& v) { return F::MVec(z0 + H * v); }, F::MVec(z), F::MMat(R), gate, F::MMat(widen));
    const auto sb = b.updateLinear(H, z0, z, R, gate, widen);
    ASSERT_EQ(sa, sb) << k;
    EXPECT_NEAR(a.nis(), b.nis(), 1e-6 * (1.0 + a.nis())) << k;
    EXPECT_NEAR(a.predictedMeasurement()(0), b.predictedMeasurement()(0), 1e-9) << k;
    EXPECT_LT((a.x() - b.x()).norm(), 1e-7 * (1.0 + a.x().norm())) << k;
    EXPECT_LT((a.P() - b.P()).norm(), 1e-6 * (1.0 + a.P().norm())) << k;
  }
}

// predictDriven, the written-out predict of the joint [state, random-walk input], equals predict() up
// to rounding: random states and covariances, a nonlinear g with a kink at 0 (as Bouc-Wen's sides),
// points at the clamp (predict()'s way) and points clear of it (the closed form), and the status,
// including a covariance that must be repaired and a non-finite state. predict()'s own rounding sets
// the tolerance: its d_2 + d_4, zero in exact arithmetic, is a few ulp of x_0' that Wi ~ 1.7e5 scales
// (the closed form is checked against exact sums in the next test).
TEST(Ukf, DrivenPredictEqualsPredict) {
  using F = Ukf<2, 1>;
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const auto g = [](double h) { return h > 0.0 ? h - 0.3 * h * h : 1.7 * h + std::sin(h); };
  const auto next = [](double gv, double f) { return std::clamp(gv + 1e-3 * f, -2.0, 2.0); };
  int clear = 0;  // steps whose points are all clear of the clamp (the closed form)
  for (int k = 0; k < 500; ++k) {
    F::Vec x(2.5 * U(rng), 20.0 * U(rng));
    const double c = (k % 7 == 0 ? 1.5 : 0.99) * U(rng), s0 = 1e-3 + std::fabs(U(rng)),
                 s1 = 0.1 + 10.0 * std::fabs(U(rng));
    F::Mat P;
    P << s0 * s0, c * s0 * s1, c * s0 * s1, s1 * s1;  // |c| > 1: indefinite, repaired
    if (k % 50 == 0) x(0) = NAN;
    F::Mat Q;
    Q << 0.1 * std::fabs(U(rng)), 0.0, 0.0, 0.2 * std::fabs(U(rng));
    F a, b;
    a.reset(x, P);
    b.reset(x, P);
    const double tol = 1e-8;
    for (int step = 0; step < 3; ++step) {
      const auto sa = a.predict([&](const F::Vec& v) { return F::Vec(next(g(v(0)), v(1)), v(1)); }, Q);
      const auto sb = b.predictDriven(g, 1e-3, 2.0, Q);
      ASSERT_EQ(sa, sb) << k;
      const double scale = 1.0 + a.P().cwiseAbs().maxCoeff();
      for (int i = 0; i < 2; ++i) {
        EXPECT_EQ(std::isnan(a.x()(i)), std::isnan(b.x()(i)));
        if (!std::isnan(a.x()(i))) {
          EXPECT_NEAR(a.x()(i), b.x()(i), tol * (1.0 + std::fabs(a.x()(i)))) << k << " step " << step;
        }
        for (int j = 0; j < 2; ++j) EXPECT_NEAR(a.P()(i, j), b.P()(i, j), tol * scale) << k << " step " << step;
      }
      EXPECT_EQ(b.P()(0, 1), b.P()(1, 0));                            // symmetric as computed
      if (sa == UkfStatus::Ok && std::fabs(a.x()(0)) < 1.5) ++clear;  // sigma points within 2e-3 of x_0
    }
  }
  EXPECT_GT(clear, 300);
}

// predictDriven's closed form against the unscented transform's sums done in long double on the same
// sigma points: g's values are the filter's (double), everything after them to ~1e-19 relative.
// Random states, covariances, slopes b and correlations, all clear of the clamp.
TEST(Ukf, DrivenPredictMatchesExactSums) {
  using F = Ukf<2, 1>;
  using LD = long double;
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  const auto g = [](double h) { return h > 0.0 ? h - 0.3 * h * h : 1.7 * h + std::sin(h); };
  for (int k = 0; k < 2000; ++k) {
    const double h = 2.0 * U(rng), f = 30.0 * U(rng), bs = k % 3 == 0 ? 1e-3 : 0.5 * U(rng);
    const double c = 0.999 * U(rng), s0 = 1e-4 + std::fabs(U(rng)), s1 = 0.01 + 10.0 * std::fabs(U(rng));
    F::Mat P, Q;
    P << s0 * s0, c * s0 * s1, c * s0 * s1, s1 * s1;
    Q << 0.1 * std::fabs(U(rng)), 0.0, 0.0, 0.2 * std::fabs(U(rng));
    F b;
    b.reset(F::Vec(h, f), P);
    ASSERT_EQ(b.predictDriven(g, bs, 1e6, Q), UkfStatus::Ok) << k;

    // The sigma points as the filter draws them: x_0 +- gamma L00 in double, the rest exact.
    const double gam = std::sqrt(2.0 + b.lambda()), l00 = std::sqrt(P(0, 0));
    const LD wi = b.wi(), central = LD(2.0) - LD(1e-6) * LD(1e-6) * LD(1e6);  // beta - alpha^2, alpha = 1e-3
    const LD l10 = LD(P(1, 0)) / LD(l00), l11 = std::sqrt(LD(P(1, 1)) - l10 * l10);
    const double o = gam * l00;
    const LD g0 = g(h), gp = g(h + o), gm = g(h - o), e = LD(gam) * l10, e2 = LD(gam) * l11;
    // d_i = X_i' - X_0', each formed exactly (X_0' itself is far larger than the d_i).
    const LD d[4][2] = {{(gp - g0) + bs * e, e}, {bs * e2, e2}, {(gm - g0) - bs * e, -e}, {-bs * e2, -e2}};
    LD m[2], Pr[2][2];
    for (int r = 0; r < 2; ++r) m[r] = wi * (((d[0][r] + d[1][r]) + d[2][r]) + d[3][r]);
    const LD mean[2] = {g0 + bs * LD(f) + m[0], LD(f) + m[1]};
    for (int r = 0; r < 2; ++r)
      for (int q = 0; q < 2; ++q) {
        LD sum = 0;
        for (int i = 0; i < 4; ++i) sum += wi * d[i][r] * d[i][q];
        Pr[r][q] = sum + central * m[r] * m[q] + LD(Q(r, q));
      }
    const double scale = 1.0 + std::max(std::fabs(double(Pr[0][0])), std::fabs(double(Pr[1][1])));
    for (int r = 0; r < 2; ++r) {
      EXPECT_NEAR(b.x()(r), double(mean[r]), 1e-13 * (1.0 + std::fabs(double(mean[r])))) << k;
      for (int q = 0; q < 2; ++q) EXPECT_NEAR(b.P()(r, q), double(Pr[r][q]), 1e-13 * scale) << k;
    }
  }
}
