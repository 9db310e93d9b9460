// OMG goal-cost estimates (Sec. III-D): the objective of a constant-velocity tail to each goal.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "pickplan/core/errors.hpp"
#include "pickplan/omg/chomp.hpp"

namespace pickplan::omg {

namespace {
// Every stride-th body point overall, as before the grouping, per link group: its first index,
// count and offset in a buffer of the strided points (size: their number).
struct StridedPoints {
  std::vector<int> first, count, offset;
  int size = 0;
  StridedPoints(const std::vector<LinkGroup>& groups, int stride)
      : first(groups.size()), count(groups.size()), offset(groups.size()) {
    for (size_t gi = 0; gi < groups.size(); ++gi) {
      const LinkGroup& grp = groups[gi];
      first[gi] = grp.begin + (stride - grp.begin % stride) % stride;
      count[gi] = first[gi] < grp.end ? (grp.end - 1 - first[gi]) / stride + 1 : 0;
      offset[gi] = size;
      size += count[gi];
    }
  }
};

// Group gi's strided points, moved by its link's pose T, into x (3 per point).
inline void place_points(const core::Transform& T, const geometry::Vertices& points, const StridedPoints& sp, int gi,
                         int stride, double* x) {
  for (int j = 0; j < sp.count[gi]; ++j)
    Eigen::Map<Eigen::Vector3d>(x + 3L * j) = T.apply(points.row(sp.first[gi] + j * stride).transpose());
}
}  // namespace

void ChompProblem::goal_costs(const Trajectory& xi, const Eigen::VectorXd& q0, int iteration, int horizon,
                              const Trajectory& goals, int time_stride, int point_stride, double* out,
                              ChompWorkspace& ws) const {
  check_trajectory(xi, q0);
  if (horizon < 1 || iteration < 0) throw std::invalid_argument("goal costs: horizon >= 1 and iteration >= 0 required");
  if (time_stride < 1 || point_stride < 1) throw std::invalid_argument("goal costs: strides must be >= 1");
  core::require_size("goal costs: goals", robot_->dof(), goals.cols(), "joint values per row");
  const int n = settings_.n;
  const int k = std::min(n - 1, static_cast<int>(std::floor(static_cast<double>(n) * iteration / horizon)));
  const Eigen::VectorXd a = k == 0 ? q0 : Eigen::VectorXd(xi.row(k - 1).transpose());
  const int L = n - k;  // waypoints of the tail after a
  const double lambda = settings_.lambda * std::pow(settings_.lambda_growth, iteration);
  const double eps = settings_.epsilon, inv_dt = 1.0 / dt_;
  const int last_t = L - settings_.obstacle_tail;  // the standoff approach is not charged, as in CHOMP
  core::RobotWorkspace& fk_cur = ws.fk[1];
  core::RobotWorkspace& fk_a = ws.fk[2];       // n >= 2: at least three
  robot_->forward_kinematics(a.data(), fk_a);  // every goal's tail starts here
  // The strided points (StridedPoints) in buffers: ws.x holds three (it has (n + 1) N >= 3 N rows):
  // the points at the tail start (the same for every goal, transformed once per call), at the
  // current and at the previous tail step; a group's previous points are reused for the speed when
  // that step transformed them (the same expression: bit-equal), else recomputed.
  const int G = static_cast<int>(groups_.size());
  const StridedPoints sp(groups_, point_stride);
  const std::vector<int>&first = sp.first, &count = sp.count, &offset = sp.offset;
  const int S = sp.size;
  double* const x_a = ws.x.data() + 6L * S;
  for (int gi = 0; gi < G; ++gi)
    place_points(fk_a.link_pose[groups_[gi].link], body_.points, sp, gi, point_stride, x_a + 3L * offset[gi]);
  std::vector<char> valid_prev(G), valid_cur(G);
  Eigen::VectorXd q(robot_->dof()), delta(robot_->dof());
  const core::Transform* prev_pose = nullptr;  // link poses of the previous tail step
  core::RobotWorkspace& fk_prev = ws.fk[0];
  for (int g = 0; g < goals.rows(); ++g) {
    delta = goals.row(g).transpose() - a;
    // Prior of a constant-velocity tail: L equal steps of delta / L.
    double f = lambda * 0.5 * delta.squaredNorm() / L * inv_dt * inv_dt;
    double obstacle = 0;
    double* x_cur = ws.x.data();
    double* x_prev = x_a;
    std::fill(valid_prev.begin(), valid_prev.end(), 1);
    prev_pose = fk_a.link_pose.data();
    for (int t = time_stride; t <= last_t; t += time_stride) {
      q = a + delta * (static_cast<double>(t) / L);
      robot_->forward_kinematics(q.data(), fk_cur);
      for (int gi = 0; gi < G; ++gi) {
        valid_cur[gi] = 0;
        const LinkGroup& grp = groups_[gi];
        const GroupReach reach = group_reach(fk_cur, grp);
        if (!reach.any()) continue;  // every point beyond epsilon: no cost
        double* xg = x_cur + 3L * offset[gi];
        const int c = count[gi];
        place_points(fk_cur.link_pose[grp.link], body_.points, sp, gi, point_stride, xg);
        valid_cur[gi] = 1;
        scene_->distances(xg, c, ws.d.data(), nullptr, eps, settings_.exclude_mask, reach.objects, reach.table);
        const core::Transform& Tp = prev_pose[grp.link];
        const double* xpg = x_prev + 3L * offset[gi];
        for (int j = 0; j < c; ++j) {
          const double d = ws.d[j];
          if (d >= eps) continue;
          const Eigen::Vector3d x = Eigen::Map<const Eigen::Vector3d>(xg + 3L * j);
          const Eigen::Vector3d xp = valid_prev[gi]
                                         ? Eigen::Vector3d(Eigen::Map<const Eigen::Vector3d>(xpg + 3L * j))
                                         : Tp.apply(body_.points.row(first[gi] + j * point_stride).transpose());
          // Speed over the strided step, times the step count it stands for.
          obstacle += chomp_cost(d, eps, nullptr) * (x - xp).norm() * inv_dt;
        }
      }
      // The current step becomes the previous one (its poses kept, its point buffer swapped in).
      std::swap(fk_prev.link_pose, fk_cur.link_pose);
      prev_pose = fk_prev.link_pose.data();
      x_prev = x_cur;
      x_cur = (x_cur == ws.x.data()) ? ws.x.data() + 3L * S : ws.x.data();
      std::swap(valid_prev, valid_cur);
    }
    out[g] = f + obstacle * point_stride;
  }
}

}  // namespace pickplan::omg
