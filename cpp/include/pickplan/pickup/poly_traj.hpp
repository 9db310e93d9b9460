#pragma once
// Per-DOF polynomials in time (Thakar et al., Sec. V-B): q_i(t) = sum_k a_ik (t / tau)^k.
// tau is a fixed time scale (seconds) that keeps the monomials well scaled; it is not a
// decision variable. Coefficients are stored DOF after DOF: [a_00..a_0d0, a_10.., ...].
#include <vector>

#include <Eigen/Core>

namespace pickplan::pickup {

class PolyTraj {
 public:
  PolyTraj() = default;
  // degrees[i] >= 0 is the degree of DOF i; time_scale > 0. Throws std::invalid_argument.
  PolyTraj(std::vector<int> degrees, double time_scale);

  int dof() const { return static_cast<int>(degrees_.size()); }
  int degree(int i) const { return degrees_.at(i); }
  int offset(int i) const { return offset_.at(i); }  // index of a_i0 in the coefficient vector
  int num_coeffs() const { return offset_.empty() ? 0 : offset_.back(); }
  double time_scale() const { return tau_; }
  const std::vector<int>& degrees() const { return degrees_; }

  // d^r/dt^r (t / tau)^k for r = 0, 1, 2.
  double basis(double t, int k, int r) const;
  // q, q', q'' at time t (any of the outputs may be null). coeffs has num_coeffs() entries.
  void eval(const double* coeffs, double t, double* q, double* qd, double* qdd) const;
  // Evaluates at many times: rows of the returned (len(times), dof) matrices.
  void eval_many(const Eigen::VectorXd& coeffs, const Eigen::VectorXd& times, Eigen::MatrixXd* q, Eigen::MatrixXd* qd,
                 Eigen::MatrixXd* qdd) const;
  // d q_i(t) / d a_ik = basis(t, k, 0); d q_i'(t) / d a_ik = basis(t, k, 1) (the map is linear).
  // Fits DOF i's coefficients by least squares to values at times (weighted rows): used for seeds.
  // weights (optional, same length) scale the residuals.
  void fit_dof(int i, const Eigen::VectorXd& times, const Eigen::VectorXd& values, double* coeffs,
               const Eigen::VectorXd& weights = Eigen::VectorXd()) const;

 private:
  std::vector<int> degrees_;
  std::vector<int> offset_;  // size dof + 1
  double tau_ = 1.0;
};

}  // namespace pickplan::pickup
