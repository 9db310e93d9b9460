#include "pickplan/pickup/poly_traj.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

#include <Eigen/Dense>

#include "pickplan/core/errors.hpp"

namespace pickplan::pickup {

PolyTraj::PolyTraj(std::vector<int> degrees, double time_scale) : degrees_(std::move(degrees)), tau_(time_scale) {
  if (!(time_scale > 0) || !std::isfinite(time_scale))
    throw std::invalid_argument("PolyTraj: time_scale must be positive and finite, got " + std::to_string(time_scale));
  offset_.assign(1, 0);
  for (size_t i = 0; i < degrees_.size(); ++i) {
    if (degrees_[i] < 0 || degrees_[i] > 12)
      throw std::invalid_argument("PolyTraj: degree of DOF " + std::to_string(i) + " must be in [0, 12], got " +
                                  std::to_string(degrees_[i]));
    offset_.push_back(offset_.back() + degrees_[i] + 1);
  }
}

double PolyTraj::basis(double t, int k, int r) const {
  if (k < r) return 0.0;
  const double s = t / tau_;
  double c = 1.0;
  for (int j = 0; j < r; ++j) c *= (k - j);
  return c * std::pow(s, k - r) / std::pow(tau_, r);
}

void PolyTraj::eval(const double* a, double t, double* q, double* qd, double* qdd) const {
  const double s = t / tau_;
  for (int i = 0; i < dof(); ++i) {
    const double* c = a + offset_[i];
    const int d = degrees_[i];
    // Horner for value and the first two derivatives in s.
    double p0 = c[d], p1 = 0.0, p2 = 0.0;
    for (int k = d - 1; k >= 0; --k) {
      p2 = p2 * s + 2.0 * p1;
      p1 = p1 * s + p0;
      p0 = p0 * s + c[k];
    }
    if (q) q[i] = p0;
    if (qd) qd[i] = p1 / tau_;
    if (qdd) qdd[i] = p2 / (tau_ * tau_);
  }
}

void PolyTraj::eval_many(const Eigen::VectorXd& coeffs, const Eigen::VectorXd& times, Eigen::MatrixXd* q,
                         Eigen::MatrixXd* qd, Eigen::MatrixXd* qdd) const {
  core::require_size("PolyTraj coefficients", num_coeffs(), coeffs.size(), "coefficients");
  const long n = times.size();
  if (q) q->resize(n, dof());
  if (qd) qd->resize(n, dof());
  if (qdd) qdd->resize(n, dof());
  Eigen::VectorXd a(dof()), b(dof()), c(dof());
  for (long j = 0; j < n; ++j) {
    eval(coeffs.data(), times[j], a.data(), b.data(), c.data());
    if (q) q->row(j) = a.transpose();
    if (qd) qd->row(j) = b.transpose();
    if (qdd) qdd->row(j) = c.transpose();
  }
}

void PolyTraj::fit_dof(int i, const Eigen::VectorXd& times, const Eigen::VectorXd& values, double* coeffs,
                       const Eigen::VectorXd& weights) const {
  if (i < 0 || i >= dof())
    throw std::invalid_argument("PolyTraj::fit_dof: DOF index " + std::to_string(i) + " out of range [0, " +
                                std::to_string(dof()) + ")");
  core::require_size("PolyTraj::fit_dof values", times.size(), values.size());
  if (weights.size()) core::require_size("PolyTraj::fit_dof weights", times.size(), weights.size());
  const int d = degrees_[i];
  Eigen::MatrixXd A(times.size(), d + 1);
  Eigen::VectorXd b = values;
  for (long r = 0; r < times.size(); ++r) {
    const double w = weights.size() ? weights[r] : 1.0;
    for (int k = 0; k <= d; ++k) A(r, k) = w * basis(times[r], k, 0);
    b[r] *= w;
  }
  Eigen::VectorXd x = A.colPivHouseholderQr().solve(b);
  for (int k = 0; k <= d; ++k) coeffs[offset_[i] + k] = x[k];
}

}  // namespace pickplan::pickup
