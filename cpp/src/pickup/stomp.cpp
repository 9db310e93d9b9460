#include "pickplan/pickup/stomp.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

#include "pickplan/core/errors.hpp"

namespace pickplan::pickup {
namespace {

struct Costs {
  Eigen::VectorXd per_step;  // state cost per waypoint
  double smooth = 0, total = 0, max_rate = 0, min_clear = 0;
  bool limits_ok = true;
};

Costs evaluate(const core::Robot& robot, const Eigen::MatrixXd& Q, double dt, const Eigen::VectorXd& rate,
               const std::vector<BodySphere>& spheres, const std::vector<SphereObstacle>& obstacles,
               const StompSettings& st, core::RobotWorkspace& ws) {
  const int N = static_cast<int>(Q.rows()), d = static_cast<int>(Q.cols()), na = d - 3;
  Costs c;
  c.per_step = Eigen::VectorXd::Zero(N);
  c.min_clear = std::numeric_limits<double>::infinity();
  for (int i = 0; i < N; ++i) {
    const Eigen::VectorXd q = Q.row(i).transpose();
    robot.forward_kinematics(q.data(), ws);
    double cost = 0.0;
    for (const auto& b : spheres)
      for (const auto& o : obstacles) {
        const double clear = (ws.link_pose[b.link].apply(b.center) - o.center).norm() - b.radius - o.radius;
        c.min_clear = std::min(c.min_clear, clear);
        cost += st.obstacle_weight * std::max(0.0, st.margin - clear);
      }
    for (int j = 0; j < na; ++j) {
      const double v = q[3 + j], lo = robot.lower_limits()[3 + j], hi = robot.upper_limits()[3 + j];
      const double viol = std::max({0.0, lo - v, v - hi});
      cost += st.limit_weight * viol;
      if (viol > 1e-12) c.limits_ok = false;
      if (i > 0 && i + 1 < N) {
        const double r = std::abs(Q(i + 1, 3 + j) - Q(i - 1, 3 + j)) / (2 * dt);
        c.max_rate = std::max(c.max_rate, r);
        const double rv = std::max(0.0, r - rate[j]);
        cost += st.limit_weight * rv;
        if (rv > 1e-9) c.limits_ok = false;
      }
    }
    c.per_step[i] = cost;
  }
  for (int i = 1; i + 1 < N; ++i)
    c.smooth +=
        (Q.row(i + 1).tail(na) - 2 * Q.row(i).tail(na) + Q.row(i - 1).tail(na)).squaredNorm() / (dt * dt * dt * dt);
  c.smooth *= dt;
  c.total = c.per_step.sum() + st.control_weight * c.smooth;
  return c;
}

}  // namespace

namespace {
void check_stomp_inputs(const core::Robot& robot, const Eigen::MatrixXd& Q0, double dt, const Eigen::VectorXd& rate,
                        const std::vector<BodySphere>& spheres, const StompSettings& st) {
  const int N = static_cast<int>(Q0.rows()), d = robot.dof(), na = d - 3;
  if (na < 1)
    throw std::invalid_argument("stomp: expected 3 base DOFs plus an arm, got " + std::to_string(d) + " DOFs");
  core::require_size("stomp: waypoints", d, Q0.cols(), "joint values per row");
  if (N < 5) throw std::invalid_argument("stomp: need at least 5 waypoints, got " + std::to_string(N));
  core::require_finite("stomp: waypoints", Q0.data(), Q0.size());
  if (!(dt > 0)) throw std::invalid_argument("stomp: dt must be positive");
  core::require_size("stomp: arm rate limits", na, rate.size(), "values");
  if (st.rollouts < 2 || st.iterations < 0) throw std::invalid_argument("stomp: need rollouts >= 2, iterations >= 0");
  for (const auto& b : spheres)
    if (b.link < 0 || b.link >= robot.num_links()) throw std::invalid_argument("stomp: body sphere link out of range");
}

// STOMP's fixed matrices for F free waypoints of N: A the second-difference operator on the whole
// sequence, R = A^T A, M = R^-1 with columns scaled to max 1/F (the update's smoothing), L the
// Cholesky factor of R^-1 (the noise's shape), scale the noise's standard deviation per unit.
struct StompOperators {
  Eigen::MatrixXd A, Rinv, M, L;
  double scale = 0;
  StompOperators(int N, int F, double noise_stddev) : A(Eigen::MatrixXd::Zero(N - 2, F)) {
    for (int r = 0; r < N - 2; ++r)
      for (int k = 0; k < 3; ++k) {
        const int col = r + k - 2, w = (k == 1) ? -2 : 1;
        if (col >= 0 && col < F) A(r, col) += w;
      }
    const Eigen::MatrixXd R = A.transpose() * A;
    Rinv = R.inverse();
    M = Rinv;
    for (int j = 0; j < F; ++j) M.col(j) *= (1.0 / F) / M.col(j).cwiseAbs().maxCoeff();
    L = Eigen::LLT<Eigen::MatrixXd>(Rinv).matrixL();
    scale = noise_stddev / L.rowwise().norm().maxCoeff();
  }
};

// The probability-weighted noise per free waypoint: rollout k's weight at step i falls with its cost
// S(k, i), normalised over the rollouts' range at that step.
Eigen::MatrixXd weighted_noise(const Eigen::MatrixXd& S, const std::vector<Eigen::MatrixXd>& eps, int N, int d,
                               const StompSettings& st) {
  Eigen::MatrixXd delta = Eigen::MatrixXd::Zero(N, d);
  for (int i = 2; i < N - 2; ++i) {
    const double lo = S.col(i).minCoeff(), hi = S.col(i).maxCoeff();
    Eigen::VectorXd p(st.rollouts);
    for (int k = 0; k < st.rollouts; ++k)
      p[k] = hi - lo < 1e-12 ? 1.0 : std::exp(-st.temperature * (S(k, i) - lo) / (hi - lo));
    p /= p.sum();
    for (int k = 0; k < st.rollouts; ++k) delta.row(i) += p[k] * eps[k].row(i);
  }
  return delta;
}

// Smooths the update (M) and adds the control-cost gradient step -R theta (scaled like STOMP's),
// then projects the free waypoints into the joint limits.
void apply_update(const core::Robot& robot, const StompOperators& op, const Eigen::MatrixXd& delta,
                  const StompSettings& st, Eigen::MatrixXd& theta) {
  const int N = static_cast<int>(theta.rows()), F = N - 4, na = robot.dof() - 3;
  for (int j = 0; j < na; ++j) {
    const Eigen::VectorXd th = theta.block(0, 3 + j, N, 1);
    Eigen::VectorXd ctrl = Eigen::VectorXd::Zero(F);
    Eigen::VectorXd acc(N - 2);
    for (int r = 0; r < N - 2; ++r) acc[r] = th[r] - 2 * th[r + 1] + th[r + 2];
    ctrl = op.A.transpose() * acc;  // gradient of 0.5 |acc|^2 w.r.t. the free waypoints
    // Exploration update smoothed by M; smoothness by a damped Newton step on 0.5 |A theta|^2
    // (R^-1 A^T acc moves the free waypoints towards the minimum-acceleration path).
    theta.block(2, 3 + j, F, 1) +=
        op.M * delta.block(2, 3 + j, F, 1) - std::min(1.0, 0.2 * st.control_weight) * (op.Rinv * ctrl);
  }
  for (int i = 2; i < N - 2; ++i)
    for (int j = 0; j < na; ++j)
      theta(i, 3 + j) = std::clamp(theta(i, 3 + j), robot.lower_limits()[3 + j], robot.upper_limits()[3 + j]);
}
}  // namespace

StompResult stomp_refine(const core::Robot& robot, const Eigen::MatrixXd& Q0, double dt, const Eigen::VectorXd& rate,
                         const std::vector<BodySphere>& spheres, const std::vector<SphereObstacle>& obstacles,
                         const StompSettings& st) {
  check_stomp_inputs(robot, Q0, dt, rate, spheres, st);
  const int N = static_cast<int>(Q0.rows()), d = robot.dof(), na = d - 3;
  const auto t0 = std::chrono::steady_clock::now();
  // Free waypoints 2 .. N-3.
  const int F = N - 4;
  StompResult res;
  core::RobotWorkspace ws(robot);
  Costs c0 = evaluate(robot, Q0, dt, rate, spheres, obstacles, st, ws);
  res.q = Q0;
  res.initial_cost = c0.total;
  res.initial_smoothness = c0.smooth;
  Costs best = c0;
  bool best_ok = c0.limits_ok;
  if (F > 0 && st.iterations > 0) {
    const StompOperators op(N, F, st.noise_stddev);
    std::mt19937 rng(st.seed);
    std::normal_distribution<double> nd(0.0, 1.0);
    Eigen::MatrixXd theta = Q0;
    std::vector<Eigen::MatrixXd> eps(st.rollouts, Eigen::MatrixXd::Zero(N, d));
    Eigen::MatrixXd S(st.rollouts, N);
    for (int it = 0; it < st.iterations; ++it) {
      for (int k = 0; k < st.rollouts; ++k) {
        eps[k].setZero();
        for (int j = 0; j < na; ++j) {
          Eigen::VectorXd z(F);
          for (int f = 0; f < F; ++f) z[f] = nd(rng);
          eps[k].block(2, 3 + j, F, 1) = op.scale * (op.L * z);
        }
        S.row(k) = evaluate(robot, theta + eps[k], dt, rate, spheres, obstacles, st, ws).per_step.transpose();
      }
      apply_update(robot, op, weighted_noise(S, eps, N, d, st), st, theta);
      Costs c = evaluate(robot, theta, dt, rate, spheres, obstacles, st, ws);
      res.iterations = it + 1;
      const bool better = (c.limits_ok && !best_ok) || (c.limits_ok == best_ok && c.total < best.total);
      if (better) {
        best = c;
        best_ok = c.limits_ok;
        res.q = theta;
      }
    }
  }
  res.final_cost = best.total;
  res.final_smoothness = best.smooth;
  res.max_rate = best.max_rate;
  res.min_clearance = best.min_clear;
  res.limits_ok = best_ok;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace pickplan::pickup
