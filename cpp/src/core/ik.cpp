#include "pickplan/core/ik.hpp"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "pickplan/core/errors.hpp"

namespace pickplan {

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

IkSolver::IkSolver(std::shared_ptr<const Robot> robot, int link, IkSettings settings, const Transform& tip)
    : robot_(std::move(robot)), link_(link), settings_(std::move(settings)), tip_(tip) {
  if (!robot_) throw std::invalid_argument("IK: robot must not be null");
  if (link < 0 || link >= robot_->num_links()) throw std::invalid_argument("IK: link index out of range");
  if (!settings_.active.empty())
    require_size("IK settings: active joint mask", robot_->dof(), static_cast<long>(settings_.active.size()), "entries");
  if (settings_.num_seeds < 1 || settings_.max_iterations < 1)
    throw std::invalid_argument("IK settings: num_seeds and max_iterations must be >= 1");
  std::mt19937 rng(settings_.seed);
  std::uniform_real_distribution<double> u(0.1, 0.9);  // away from the limits, where descent stalls
  for (int s = 1; s < settings_.num_seeds; ++s) {
    Eigen::VectorXd v(robot_->dof());
    for (int j = 0; j < robot_->dof(); ++j) v[j] = u(rng);
    spread_.push_back(v);
  }
}

std::pair<double, double> IkSolver::pose_error(const Eigen::VectorXd& q, const Transform& target) const {
  RobotWorkspace ws(*robot_);
  robot_->forward_kinematics(q.data(), ws);
  const Transform T = ws.link_pose[link_] * tip_;
  return {(target.p - T.p).norm(), rotation_log(target.R * T.R.transpose()).norm()};
}

IkSolution IkSolver::solve(const Transform& target, const Eigen::VectorXd& seed) const {
  const Robot& r = *robot_;
  const int d = r.dof();
  robot_->check_configuration(seed.data(), seed.size());
  RobotWorkspace ws(r);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, d);
  Eigen::Matrix<double, 6, 1> e;
  IkSolution sol;
  sol.q = seed.cwiseMax(r.lower_limits()).cwiseMin(r.upper_limits());
  double lambda = settings_.damping;
  auto error = [&](const Eigen::VectorXd& q, Eigen::Matrix<double, 6, 1>& err) {
    r.forward_kinematics(q.data(), ws, link_);
    const Transform T = ws.link_pose[link_] * tip_;
    err.head<3>() = target.p - T.p;
    err.tail<3>() = rotation_log(target.R * T.R.transpose());
    return T;
  };
  Transform T = error(sol.q, e);
  double cost = e.squaredNorm();
  Eigen::VectorXd q_new(d);
  int stalled = 0;  // iterations without a meaningful decrease: a local minimum or a limit
  for (int it = 0; it < settings_.max_iterations && stalled < 8; ++it) {
    sol.iterations = it;
    if (e.head<3>().norm() < settings_.position_tolerance && e.tail<3>().norm() < settings_.rotation_tolerance) {
      sol.converged = true;
      break;
    }
    r.point_jacobian(ws, link_, tip_.p, J);
    for (int j = 0; j < d; ++j) {
      const bool active = settings_.active.empty() || settings_.active[j];
      if (!active) J.col(j).setZero();
    }
    const Eigen::Matrix<double, 6, 6> JJt = J * J.transpose();
    Eigen::VectorXd dq = J.transpose() * (JJt + lambda * Eigen::Matrix<double, 6, 6>::Identity()).ldlt().solve(e);
    const double m = dq.cwiseAbs().maxCoeff();
    if (m > settings_.max_step) dq *= settings_.max_step / m;
    q_new = (sol.q + dq).cwiseMax(r.lower_limits()).cwiseMin(r.upper_limits());
    Eigen::Matrix<double, 6, 1> e_new;
    const Transform T_new = error(q_new, e_new);
    const double cost_new = e_new.squaredNorm();
    stalled = cost_new < cost * (1 - 1e-3) ? 0 : stalled + 1;
    if (cost_new < cost) {
      sol.q = q_new;
      e = e_new;
      T = T_new;
      cost = cost_new;
      lambda = std::max(lambda * 0.3, 1e-8);
    } else {
      lambda = std::min(lambda * 10, 1e4);
      r.forward_kinematics(sol.q.data(), ws);  // restore the workspace for the next Jacobian
    }
  }
  sol.position_error = e.head<3>().norm();
  sol.rotation_error = e.tail<3>().norm();
  sol.converged = sol.position_error < settings_.position_tolerance && sol.rotation_error < settings_.rotation_tolerance;
  return sol;
}

namespace {
Eigen::VectorXd seed_from_spread(const Robot& r, const Eigen::VectorXd& unit, const Eigen::VectorXd& start,
                                 const std::vector<bool>& active) {
  Eigen::VectorXd q = start;
  for (int j = 0; j < r.dof(); ++j) {
    if (!active.empty() && !active[j]) continue;
    const double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    const double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = lo + unit[j] * (hi - lo);
  }
  return q;
}
}  // namespace

Eigen::VectorXd IkSolver::seed_configuration(int k, const Eigen::VectorXd& start) const {
  if (k <= 0) return start;
  return seed_from_spread(*robot_, spread_.at(k - 1), start, settings_.active);
}

std::vector<IkSolution> IkSolver::solve_all(const Transform& target, const Eigen::VectorXd& start) const {
  std::vector<IkSolution> out;
  auto consider = [&](IkSolution s) {
    if (!s.converged) return;
    for (const auto& o : out)
      if ((o.q - s.q).cwiseAbs().maxCoeff() < settings_.duplicate_tolerance) return;
    out.push_back(std::move(s));
  };
  consider(solve(target, start));
  for (const auto& unit : spread_) consider(solve(target, seed_from_spread(*robot_, unit, start, settings_.active)));
  std::stable_sort(out.begin(), out.end(), [&](const IkSolution& a, const IkSolution& b) {
    return (a.q - start).squaredNorm() < (b.q - start).squaredNorm();
  });
  return out;
}

IkSolution IkSolver::solve_any(const Transform& target, const Eigen::VectorXd& start) const {
  IkSolution best = solve(target, start);
  if (best.converged) return best;
  for (const auto& unit : spread_) {
    IkSolution s = solve(target, seed_from_spread(*robot_, unit, start, settings_.active));
    if (s.converged) return s;
    if (s.position_error + s.rotation_error < best.position_error + best.rotation_error) best = s;
  }
  return best;
}

}  // namespace pickplan
