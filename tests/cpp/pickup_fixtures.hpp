#pragma once
// Shared by the pick-up NLP tests: the mobile UR5, fast settings, and central-difference checks
// of a PickupConstraints' Jacobian and Lagrangian Hessian.
#include <algorithm>
#include <cmath>
#include <string>

#include "pickplan/core/robot.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::test {

inline core::Robot load_mobile_ur5() {
  return core::Robot::from_urdf_file(std::string(PICKPLAN_TEST_DATA_DIR) + "/../../../assets/mobile_ur5.urdf");
}

inline pickup::PickupSettings fast_pickup_settings() {
  pickup::PickupSettings st;
  st.samples_per_interval = 6;
  return st;
}

// Worst |fd - J| / (1 + |J|) over all entries, fd the central difference of g (step 1e-6 relative).
inline double jacobian_fd_error(const pickup::PickupConstraints& c, const Eigen::VectorXd& x) {
  const Eigen::MatrixXd J = c.dense_jacobian(x);
  const int m = c.num_constraints();
  Eigen::VectorXd gp(m), gm(m);
  double worst = 0.0;
  for (int j = 0; j < c.num_vars(); ++j) {
    const double h = 1e-6 * std::max(1.0, std::abs(x[j]));
    Eigen::VectorXd xp = x, xm = x;
    xp[j] += h;
    xm[j] -= h;
    c.eval_g(xp.data(), gp.data());
    c.eval_g(xm.data(), gm.data());
    const Eigen::VectorXd fd = (gp - gm) / (2 * h);
    for (int i = 0; i < m; ++i) worst = std::max(worst, std::abs(fd[i] - J(i, j)) / (1.0 + std::abs(J(i, j))));
  }
  return worst;
}

// Worst relative error of the Lagrangian Hessian H against central differences of J(x)^T lambda
// (step 1e-5 relative).
inline double hessian_fd_error(const pickup::PickupConstraints& c, const Eigen::VectorXd& x, const Eigen::VectorXd& lam,
                               const Eigen::MatrixXd& H) {
  double worst = 0.0;
  for (int j = 0; j < c.num_vars(); ++j) {
    const double h = 1e-5 * std::max(1.0, std::abs(x[j]));
    Eigen::VectorXd xp = x, xm = x;
    xp[j] += h;
    xm[j] -= h;
    const Eigen::VectorXd fd =
        (c.dense_jacobian(xp).transpose() * lam - c.dense_jacobian(xm).transpose() * lam) / (2 * h);
    for (int i = 0; i < c.num_vars(); ++i)
      worst = std::max(worst, std::abs(fd[i] - H(i, j)) / (1.0 + std::abs(H(i, j))));
  }
  return worst;
}

}  // namespace pickplan::test
