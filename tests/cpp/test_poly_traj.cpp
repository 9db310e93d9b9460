// PolyTraj (Thakar et al. Sec. V-B polynomials) against known polynomials, closed-form
// derivatives and finite differences; the least-squares fit against exact data and the normal
// equations of a weighted line fit.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/pickup/poly_traj.hpp"

using namespace pickplan::pickup;
namespace test = pickplan::test;

TEST(PolyTraj, KnownCubicAndItsDerivatives) {
  // q(t) = 1 + 2 s - 3 s^2 + 0.5 s^3 with s = t / tau, tau = 2.
  const double tau = 2.0;
  PolyTraj p({3}, tau);
  const double a[] = {1.0, 2.0, -3.0, 0.5};
  for (double t : {0.0, 0.3, 1.0, 1.7, 2.5}) {
    const double s = t / tau;
    double q, qd, qdd;
    p.eval(a, t, &q, &qd, &qdd);
    EXPECT_NEAR(q, 1 + 2 * s - 3 * s * s + 0.5 * s * s * s, 1e-14);
    EXPECT_NEAR(qd, (2 - 6 * s + 1.5 * s * s) / tau, 1e-14);
    EXPECT_NEAR(qdd, (-6 + 3 * s) / (tau * tau), 1e-14);
  }
}

TEST(PolyTraj, BasisIsTheScaledMonomialAndItsDerivatives) {
  const double tau = 1.5;
  PolyTraj p({6}, tau);
  const double t = 0.8, s = t / tau;
  for (int k = 0; k <= 6; ++k) {
    EXPECT_NEAR(p.basis(t, k, 0), std::pow(s, k), 1e-14);
    EXPECT_NEAR(p.basis(t, k, 1), k == 0 ? 0.0 : k * std::pow(s, k - 1) / tau, 1e-13);
    EXPECT_NEAR(p.basis(t, k, 2), k < 2 ? 0.0 : k * (k - 1) * std::pow(s, k - 2) / (tau * tau), 1e-13);
  }
}

// Moved from test_pickup_nlp.cpp.
TEST(PolyTraj, DerivativesMatchFiniteDifferences) {
  PolyTraj tr({3, 5, 0, 4}, 7.0);
  EXPECT_EQ(tr.num_coeffs(), 4 + 6 + 1 + 5);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-2, 2);
  Eigen::VectorXd a(tr.num_coeffs());
  for (int k = 0; k < a.size(); ++k) a[k] = u(rng);
  const double h = 1e-5;
  for (double t : {0.0, 0.3, 2.5, 9.0}) {
    double q[4], qd[4], qdd[4], qp[4], qm[4], dp[4], dm[4];
    tr.eval(a.data(), t, q, qd, qdd);
    tr.eval(a.data(), t + h, qp, dp, nullptr);
    tr.eval(a.data(), t - h, qm, dm, nullptr);
    for (int i = 0; i < 4; ++i) {
      EXPECT_NEAR(qd[i], (qp[i] - qm[i]) / (2 * h), 1e-7 * (1 + std::abs(qd[i])));
      EXPECT_NEAR(qdd[i], (dp[i] - dm[i]) / (2 * h), 1e-6 * (1 + std::abs(qdd[i])));
      // Linear in the coefficients: basis functions are the derivatives w.r.t. a_ik.
      double direct = 0.0, directd = 0.0;
      for (int k = 0; k <= tr.degree(i); ++k) {
        direct += a[tr.offset(i) + k] * tr.basis(t, k, 0);
        directd += a[tr.offset(i) + k] * tr.basis(t, k, 1);
      }
      EXPECT_NEAR(q[i], direct, 1e-10 * (1 + std::abs(q[i])));
      EXPECT_NEAR(qd[i], directd, 1e-10 * (1 + std::abs(qd[i])));
    }
  }
  EXPECT_THROW(PolyTraj({3}, 0.0), std::invalid_argument);
}

TEST(PolyTraj, EvalManyStacksSingleEvaluations) {
  PolyTraj p({2, 4}, 1.0);
  Eigen::VectorXd a(p.num_coeffs()), times(4);
  a << 0.5, -1.0, 2.0, 0.1, 0.2, 0.3, 0.4, 0.5;
  times << 0.0, 0.25, 0.5, 1.0;
  Eigen::MatrixXd Q, Qd, Qdd;
  p.eval_many(a, times, &Q, &Qd, &Qdd);
  ASSERT_EQ(Q.rows(), 4);
  ASSERT_EQ(Q.cols(), 2);
  for (int j = 0; j < 4; ++j) {
    double q[2], qd[2], qdd[2];
    p.eval(a.data(), times[j], q, qd, qdd);
    for (int i = 0; i < 2; ++i) {
      EXPECT_EQ(Q(j, i), q[i]);
      EXPECT_EQ(Qd(j, i), qd[i]);
      EXPECT_EQ(Qdd(j, i), qdd[i]);
    }
  }
}

TEST(PolyTraj, FitRecoversAPolynomialFromItsSamples) {
  PolyTraj p({1, 4}, 2.0);
  Eigen::VectorXd truth(p.num_coeffs());
  truth << 7.0, 7.0, 0.3, -1.2, 0.8, 2.0, -0.5;
  Eigen::VectorXd times = Eigen::VectorXd::LinSpaced(11, 0.0, 2.0), values(11);
  for (int j = 0; j < 11; ++j) {
    double q[2];
    p.eval(truth.data(), times[j], q, nullptr, nullptr);
    values[j] = q[1];
  }
  Eigen::VectorXd fit = Eigen::VectorXd::Zero(p.num_coeffs());
  p.fit_dof(1, times, values, fit.data());
  for (int k = 0; k <= 4; ++k) EXPECT_NEAR(fit[p.offset(1) + k], truth[p.offset(1) + k], 1e-10) << k;
  EXPECT_EQ(fit[0], 0.0);  // the other DOF's coefficients are left alone
  EXPECT_EQ(fit[1], 0.0);
}

TEST(PolyTraj, WeightedLineFitSolvesTheNormalEquations) {
  // Weighted least squares of a line a0 + a1 t to (t, y) with residual weights w: minimise
  // sum w^2 (a0 + a1 t - y)^2, closed form from the 2 x 2 normal equations.
  PolyTraj p({1}, 1.0);
  Eigen::VectorXd t(5), y(5), w(5);
  t << 0.0, 0.5, 1.0, 1.5, 2.0;
  y << 0.1, 0.9, 2.2, 2.8, 4.3;
  w << 1.0, 2.0, 0.5, 1.0, 3.0;
  double S = 0, St = 0, Stt = 0, Sy = 0, Sty = 0;
  for (int j = 0; j < 5; ++j) {
    const double v = w[j] * w[j];
    S += v, St += v * t[j], Stt += v * t[j] * t[j], Sy += v * y[j], Sty += v * t[j] * y[j];
  }
  const double det = S * Stt - St * St;
  const double a0 = (Stt * Sy - St * Sty) / det, a1 = (S * Sty - St * Sy) / det;
  double fit[2];
  p.fit_dof(0, t, y, fit, w);
  EXPECT_NEAR(fit[0], a0, 1e-12);
  EXPECT_NEAR(fit[1], a1, 1e-12);
}

TEST(PolyTraj, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  expect_invalid_argument([] { PolyTraj({3, 13}, 1.0); }, "degree of DOF 1 must be in [0, 12], got 13");
  expect_invalid_argument([] { PolyTraj({-1}, 1.0); }, "degree of DOF 0");
  expect_invalid_argument([] { PolyTraj({3}, 0.0); }, "time_scale must be positive");
  expect_invalid_argument([] { PolyTraj({3}, NAN); }, "time_scale must be positive");
  PolyTraj p({2, 3}, 1.0);
  Eigen::MatrixXd Q;
  expect_invalid_argument(
      [&] { p.eval_many(Eigen::VectorXd::Zero(6), Eigen::VectorXd::Zero(2), &Q, nullptr, nullptr); },
      "expected 7 coefficients, got 6");
  double c[7];
  const Eigen::VectorXd t3 = Eigen::VectorXd::LinSpaced(3, 0, 1), t4 = Eigen::VectorXd::LinSpaced(4, 0, 1);
  expect_invalid_argument([&] { p.fit_dof(0, t3, t4, c); }, "values: expected 3 values, got 4");
  expect_invalid_argument([&] { p.fit_dof(0, t3, t3, c, t4); }, "weights: expected 3 values, got 4");
  expect_invalid_argument([&] { p.fit_dof(2, t3, t3, c); }, "DOF index 2 out of range [0, 2)");
}
