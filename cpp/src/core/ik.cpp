#include "pickplan/core/ik.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "pickplan/core/errors.hpp"

namespace pickplan::core {

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

namespace {

using Vector6 = Eigen::Matrix<double, 6, 1>;
using Matrix6 = Eigen::Matrix<double, 6, 6>;

// sine_axis: below this |sin(angle)|, with the angle past 90 degrees, the cross products vanish
// half a turn from the target; the rotation vector gives the step a direction there.
constexpr double kVanishingSine = 1e-9;

void require(bool ok, const char* what) {
  if (!ok) throw std::invalid_argument(std::string("IK settings: ") + what);
}

Eigen::VectorXd joint_weights(const DlsSettings& s, int dof) {
  return s.weights.empty() ? Eigen::VectorXd::Ones(dof)
                           : Eigen::Map<const Eigen::VectorXd>(s.weights.data(), dof).eval();
}

}  // namespace

void validate(const DlsSettings& s, const Robot& robot) {
  if (!s.weights.empty())
    require_size("IK settings: weights", robot.dof(), static_cast<long>(s.weights.size()), "entries (one per joint)");
  for (double w : s.weights) require(std::isfinite(w) && w >= 0, "weights must be finite and >= 0");
  require(s.max_iterations >= 1, "max_iterations must be >= 1");
  require(s.position_tolerance >= 0 && s.rotation_tolerance >= 0, "tolerances must be >= 0");
  require(s.damping > 0, "damping must be > 0");
  require(s.damping_decrease > 0 && s.damping_decrease <= 1, "damping_decrease must be in (0, 1]");
  require(s.damping_increase >= 1, "damping_increase must be >= 1");
  require(s.min_damping > 0 && s.min_damping <= s.max_damping, "need 0 < min_damping <= max_damping");
  require(s.min_relative_decrease >= 0 && s.max_stalled_iterations >= 0,
          "min_relative_decrease and max_stalled_iterations must be >= 0");
  require(s.max_step > 0, "max_step must be > 0");
  require(s.limit_margin >= 0, "limit_margin must be >= 0");
}

namespace {

void check_link(const Robot& r, int link) {
  if (link < 0 || link >= r.num_links())
    throw std::invalid_argument("IK: link index " + std::to_string(link) + " out of range [0, " +
                                std::to_string(r.num_links()) + ")");
}

void check_problem(const Robot& r, const Transform& target, const Eigen::VectorXd& seed) {
  require_size("IK seed", r.dof(), static_cast<long>(seed.size()), "joint values");
  require_finite("IK seed", seed.data(), static_cast<long>(seed.size()));
  require_finite("IK target position", target.p.data(), 3);
  require_finite("IK target rotation", target.R.data(), 9);
}

// The descent of solve_ik, its arguments already checked.
IkSolution descend(const Robot& r, int link, const Transform& tip, const Transform& target, const Eigen::VectorXd& seed,
                   const DlsSettings& s) {
  const int d = r.dof();
  const bool pose = s.task == IkTask::pose;
  const Eigen::VectorXd w = joint_weights(s, d);
  // Frozen joints get infinite bounds: the clamp leaves them at the seed's values.
  const double inf = std::numeric_limits<double>::infinity();
  Eigen::VectorXd lo(d), hi(d);
  for (int j = 0; j < d; ++j) {
    lo[j] = w[j] > 0 ? r.lower_limits()[j] + s.limit_margin : -inf;
    hi[j] = w[j] > 0 ? r.upper_limits()[j] - s.limit_margin : inf;
  }
  RobotWorkspace ws(r);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, d), Jw(6, d);
  // FK of the links up to `link` into ws, the error e and the rotation angle (rad).
  auto error = [&](const Eigen::VectorXd& q, Vector6& e) {
    r.forward_kinematics(q.data(), ws, link);
    const Transform T = ws.link_pose[link] * tip;
    e.head<3>() = target.p - T.p;
    if (s.rotation_error == IkRotationError::angle_axis) {
      e.tail<3>() = rotation_log(target.R * T.R.transpose());
      return e.tail<3>().norm();
    }
    e.tail<3>() = 0.5 * (T.R.col(0).cross(target.R.col(0)) + T.R.col(1).cross(target.R.col(1)) +
                         T.R.col(2).cross(target.R.col(2)));
    const double sine = e.tail<3>().norm(), cosine = 0.5 * ((T.R.transpose() * target.R).trace() - 1.0);
    if (sine < kVanishingSine && cosine < 0)
      e.tail<3>() = rotation_log(target.R * T.R.transpose());  // half a turn away
    return std::atan2(sine, cosine);
  };
  auto cost = [&](const Vector6& e) { return pose ? e.squaredNorm() : e.head<3>().squaredNorm(); };
  auto reached = [&](const Vector6& e, double angle) {
    return e.head<3>().norm() < s.position_tolerance && (!pose || angle < s.rotation_tolerance);
  };

  IkSolution sol;
  sol.q = seed.cwiseMax(lo).cwiseMin(hi);
  Vector6 e, e_new;
  double angle = error(sol.q, e);
  double c = cost(e), lambda = s.damping;
  Eigen::VectorXd q_new(d), dq(d);
  int stalled = 0;
  for (int it = 0; it < s.max_iterations && !reached(e, angle); ++it) {
    if (s.max_stalled_iterations > 0 && stalled >= s.max_stalled_iterations) break;
    sol.iterations = it + 1;
    r.point_jacobian(ws, link, tip.p, J);
    Jw = J * w.asDiagonal();
    const Matrix6 A = Jw * J.transpose() + lambda * Matrix6::Identity();
    Vector6 y = Vector6::Zero();
    if (pose)
      y = A.ldlt().solve(e);
    else
      y.head<3>() = A.topLeftCorner<3, 3>().ldlt().solve(e.head<3>());
    dq = Jw.transpose() * y;
    const double size = s.step_norm == IkStepNorm::max_abs ? dq.cwiseAbs().maxCoeff() : dq.norm();
    if (size > s.max_step) dq *= s.max_step / size;
    q_new = (sol.q + dq).cwiseMax(lo).cwiseMin(hi);
    const double angle_new = error(q_new, e_new);
    const double c_new = cost(e_new);
    stalled = c_new < c * (1 - s.min_relative_decrease) ? 0 : stalled + 1;
    if (s.damping_schedule == IkDamping::fixed || c_new < c) {
      sol.q = q_new;
      e = e_new;
      angle = angle_new;
      c = c_new;
      if (s.damping_schedule == IkDamping::adaptive) lambda = std::max(lambda * s.damping_decrease, s.min_damping);
    } else {
      lambda = std::min(lambda * s.damping_increase, s.max_damping);
      r.forward_kinematics(sol.q.data(), ws, link);  // the workspace back at sol.q for the next Jacobian
    }
  }
  sol.position_error = e.head<3>().norm();
  sol.rotation_error = angle;
  sol.converged = reached(e, angle);
  return sol;
}

}  // namespace

IkSolution solve_ik(const Robot& robot, int link, const Transform& tip, const Transform& target,
                    const Eigen::VectorXd& seed, const DlsSettings& settings) {
  check_link(robot, link);
  check_problem(robot, target, seed);
  validate(settings, robot);
  return descend(robot, link, tip, target, seed, settings);
}

IkSolver::IkSolver(std::shared_ptr<const Robot> robot, int link, IkSettings settings, const Transform& tip)
    : robot_(std::move(robot)), link_(link), settings_(std::move(settings)), tip_(tip) {
  if (!robot_) throw std::invalid_argument("IK: robot must not be null");
  check_link(*robot_, link);
  validate(settings_, *robot_);
  if (settings_.num_seeds < 1) throw std::invalid_argument("IK settings: num_seeds must be >= 1");
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
  check_problem(*robot_, target, seed);  // the link and the settings were checked on construction
  return descend(*robot_, link_, tip_, target, seed, settings_);
}

std::vector<IkSolution> IkSolver::solve_path(const std::vector<Transform>& targets, const Eigen::VectorXd& seed) const {
  std::vector<IkSolution> out;
  out.reserve(targets.size());
  for (const Transform& target : targets) out.push_back(solve(target, out.empty() ? seed : out.back().q));
  return out;
}

namespace {
Eigen::VectorXd seed_from_spread(const Robot& r, const Eigen::VectorXd& unit, const Eigen::VectorXd& start,
                                 const std::vector<double>& weights) {
  Eigen::VectorXd q = start;
  for (int j = 0; j < r.dof(); ++j) {
    if (!weights.empty() && !(weights[j] > 0)) continue;  // frozen joints keep the start's values
    const double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    const double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = lo + unit[j] * (hi - lo);
  }
  return q;
}
}  // namespace

Eigen::VectorXd IkSolver::seed_configuration(int k, const Eigen::VectorXd& start) const {
  if (k <= 0) return start;
  return seed_from_spread(*robot_, spread_.at(k - 1), start, settings_.weights);
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
  for (const auto& unit : spread_) consider(solve(target, seed_from_spread(*robot_, unit, start, settings_.weights)));
  std::stable_sort(out.begin(), out.end(), [&](const IkSolution& a, const IkSolution& b) {
    return (a.q - start).squaredNorm() < (b.q - start).squaredNorm();
  });
  return out;
}

IkSolution IkSolver::solve_any(const Transform& target, const Eigen::VectorXd& start) const {
  IkSolution best = solve(target, start);
  if (best.converged) return best;
  for (const auto& unit : spread_) {
    IkSolution s = solve(target, seed_from_spread(*robot_, unit, start, settings_.weights));
    if (s.converged) return s;
    if (s.position_error + s.rotation_error < best.position_error + best.rotation_error) best = s;
  }
  return best;
}

}  // namespace pickplan::core
