// OMG goal-cost estimates (Sec. III-D): the objective of a constant-velocity tail to each goal.
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "pickplan/omg/chomp.hpp"
#include "pickplan/core/errors.hpp"

namespace pickplan {

void ChompProblem::goal_costs(const Trajectory& xi, const Eigen::VectorXd& q0, int iteration, int horizon,
                              const Trajectory& goals, int time_stride, int point_stride, double* out,
                              ChompWorkspace& ws) const {
  check_trajectory(xi, q0);
  if (horizon < 1 || iteration < 0) throw std::invalid_argument("goal costs: horizon >= 1 and iteration >= 0 required");
  if (time_stride < 1 || point_stride < 1) throw std::invalid_argument("goal costs: strides must be >= 1");
  require_size("goal costs: goals", robot_->dof(), goals.cols(), "joint values per row");
  const int n = settings_.n;
  const int k = std::min(n - 1, static_cast<int>(std::floor(static_cast<double>(n) * iteration / horizon)));
  const Eigen::VectorXd a = k == 0 ? q0 : Eigen::VectorXd(xi.row(k - 1).transpose());
  const int L = n - k;  // waypoints of the tail after a
  const double lambda = settings_.lambda * std::pow(settings_.lambda_growth, iteration);
  const double eps = settings_.epsilon, inv_dt = 1.0 / dt_;
  const int last_t = L - settings_.obstacle_tail;  // the standoff approach is not charged, as in CHOMP
  RobotWorkspace& fk_prev = ws.fk[0];
  RobotWorkspace& fk_cur = ws.fk[1];
  RobotWorkspace& fk_a = ws.fk[2];  // n >= 2: at least three
  robot_->forward_kinematics(a.data(), fk_a);  // every goal's tail starts here
  Eigen::VectorXd q(robot_->dof());
  for (int g = 0; g < goals.rows(); ++g) {
    const Eigen::VectorXd delta = goals.row(g).transpose() - a;
    // Prior of a constant-velocity tail: L equal steps of delta / L.
    double f = lambda * 0.5 * delta.squaredNorm() / L * inv_dt * inv_dt;
    double obstacle = 0;
    fk_prev.link_pose = fk_a.link_pose;
    for (int t = time_stride; t <= last_t; t += time_stride) {
      q = a + delta * (static_cast<double>(t) / L);
      robot_->forward_kinematics(q.data(), fk_cur);
      for (const LinkGroup& grp : groups_) {
        const GroupReach reach = group_reach(fk_cur, grp);
        if (!reach.any()) continue;  // every point beyond epsilon: no cost
        const Transform& T = fk_cur.link_pose[grp.link];
        // Every point_stride-th body point overall, as before the grouping: transformed into
        // ws.x and looked up in one batch (ws.x, ws.d are scratch here).
        const int first = grp.begin + (point_stride - grp.begin % point_stride) % point_stride;
        long count = 0;
        for (int u = first; u < grp.end; u += point_stride, ++count)
          Eigen::Map<Eigen::Vector3d>(ws.x.data() + 3 * count) = T.apply(body_.points.row(u).transpose());
        scene_->distances(ws.x.data(), count, ws.d.data(), nullptr, eps, settings_.exclude_mask, reach.objects,
                          reach.table);
        const Transform& Tp = fk_prev.link_pose[grp.link];
        for (long j = 0; j < count; ++j) {
          const double d = ws.d[j];
          if (d >= eps) continue;
          const Eigen::Vector3d x = Eigen::Map<const Eigen::Vector3d>(ws.x.data() + 3 * j);
          const Eigen::Vector3d xp = Tp.apply(body_.points.row(first + j * point_stride).transpose());
          // Speed over the strided step, times the step count it stands for.
          obstacle += chomp_cost(d, eps, nullptr) * (x - xp).norm() * inv_dt;
        }
      }
      std::swap(fk_prev.link_pose, fk_cur.link_pose);
    }
    out[g] = f + obstacle * point_stride;
  }
}

}  // namespace pickplan
