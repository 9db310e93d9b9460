#include "pickplan/omg/metrics.hpp"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include "pickplan/core/errors.hpp"

namespace pickplan::omg {

Trajectory interpolate(const Eigen::VectorXd& q0, const Trajectory& xi, int steps) {
  if (steps < 2) throw std::invalid_argument("interpolate: steps must be >= 2, got " + std::to_string(steps));
  if (xi.rows() < 1) throw std::invalid_argument("interpolate: the trajectory has no waypoints");
  core::require_size("interpolate: trajectory columns", q0.size(), xi.cols(), "joint values (the size of q0)");
  const int n = static_cast<int>(xi.rows());
  Trajectory out(steps, xi.cols());
  for (int s = 0; s < steps; ++s) {
    const double pos = static_cast<double>(s) * n / (steps - 1);
    const int i = std::min(static_cast<int>(pos), n - 1);
    const double f = pos - i;
    const Eigen::RowVectorXd a = i == 0 ? Eigen::RowVectorXd(q0.transpose()) : Eigen::RowVectorXd(xi.row(i - 1));
    out.row(s) = (1 - f) * a + f * xi.row(i);
  }
  return out;
}

double object_clearance(const ChompProblem& problem, const double* q, std::uint64_t exclude_mask, double cap,
                        core::RobotWorkspace& ws) {
  const geometry::SceneSdf& scene = problem.scene();
  const BodyPoints& body = problem.body();
  problem.robot().forward_kinematics(q, ws);
  double out = cap;
  for (const LinkGroup& grp : problem.groups()) {
    const core::Transform& T = ws.link_pose[grp.link];
    // Objects only (the table is not measured here), so links near the table are not kept for it.
    if (scene.part_lower_bounds(T.apply(grp.center), exclude_mask).objects - grp.radius >= out) continue;
    for (int u = grp.begin; u < grp.end; ++u)
      out = std::min(out, scene.distance_unmerged(T.apply(body.points.row(u).transpose()), nullptr, out,
                                                  exclude_mask | geometry::SceneSdf::kTableBit));
  }
  return out;
}

TrajectoryMetrics evaluate_trajectory(const ChompProblem& problem, const Eigen::VectorXd& q0, const Trajectory& xi,
                                      const MetricSettings& s, bool stop_at_failure) {
  problem.check_trajectory(xi, q0);
  TrajectoryMetrics m;
  m.smoothness = problem.prior(xi, q0, nullptr);
  if (stop_at_failure && !(m.smoothness < s.smoothness_threshold)) return m;  // success needs both
  // An object distance changes a metric only below this: the running minimum (min_clearance), the
  // collision padding, or the clearance the test demands.
  auto object_cutoff = [&m, &s] {
    return std::max({m.min_clearance, s.collision_padding, s.clearance, s.tail_clearance});
  };
  const Trajectory dense = interpolate(q0, xi, s.steps);
  const core::Robot& robot = problem.robot();
  const BodyPoints& body = problem.body();
  const geometry::SceneSdf& scene = problem.scene();
  std::uint64_t all_objects = 0;
  for (int i = 0; i < scene.num_objects(); ++i) all_objects |= std::uint64_t{1} << i;
  core::RobotWorkspace ws(robot);
  const double inf = std::numeric_limits<double>::infinity();
  // Distances are measured up to `cap`; links whose bounding sphere is farther from everything
  // are skipped (exact: no point of theirs can change a metric). The per-object grids are the
  // reference here, not the merged grid the optimizer uses.
  const double cap = std::max({s.epsilon, s.clearance, s.tail_clearance, s.collision_padding, s.table_clearance});
  m.min_clearance = cap;
  m.min_table_clearance = cap;
  const int n = static_cast<int>(xi.rows());
  // Dense steps at or after this one lie on the approach tail (waypoints n - tail .. n).
  const double tail_start =
      s.tail_waypoints > 0 ? static_cast<double>(n - s.tail_waypoints) / n * (s.steps - 1) : s.steps;
  bool transit_free = true, table_free = true, target_free = true;
  // The target alone (every other object and the table left out), measured in the transit when asked.
  const std::uint64_t only_target = (all_objects & ~s.exclude_mask) | geometry::SceneSdf::kTableBit;
  const bool measure_target = s.transit_target_clearance > -inf && (all_objects & s.exclude_mask) != 0;
  const double target_cut = std::max(s.transit_target_clearance, 0.0) + 1e-3;  // beyond: clear
  // ... on every dense step before the pre-grasp (the tail's first waypoint; the goal set checks the
  // approach from there), the segment into it included.
  const double target_end =
      s.tail_waypoints > 0 ? static_cast<double>(n - s.tail_waypoints + 1) / n * (s.steps - 1) : s.steps;
  for (int t = 0; t < dense.rows(); ++t) {
    robot.forward_kinematics(dense.row(t).data(), ws);
    const double need = t >= tail_start ? s.tail_clearance : s.clearance;
    const bool target_step = measure_target && t < target_end;
    double step_min = inf;
    for (const LinkGroup& grp : problem.groups()) {
      const core::Transform& T = ws.link_pose[grp.link];
      if (target_step && scene.part_lower_bounds(T.apply(grp.center), only_target).objects - grp.radius < target_cut) {
        for (int u = grp.begin; u < grp.end; ++u)
          target_free = target_free && scene.distance_unmerged(T.apply(body.points.row(u).transpose()), nullptr,
                                                               target_cut, only_target) >= s.transit_target_clearance;
      }
      // Beyond its cutoff a part reads as the cap (exact: its true distance is beyond the cutoff), for a
      // whole group by its bound.
      const double obj_cut = object_cutoff();
      const double table_cut = std::max({m.min_table_clearance, s.collision_padding, s.table_clearance});
      const geometry::SceneSdf::PartBounds b = scene.part_lower_bounds(T.apply(grp.center), s.exclude_mask);
      const bool objects_near = b.objects - grp.radius < obj_cut, table_near = b.table - grp.radius < table_cut;
      if (!objects_near && !table_near) continue;
      const bool support = grp.link < 64 && ((s.support_link_mask >> grp.link) & 1u);
      const double table_need = support ? std::min(s.table_clearance, -s.support_tolerance) : s.table_clearance;
      for (int u = grp.begin; u < grp.end; ++u) {
        const Eigen::Vector3d x = T.apply(body.points.row(u).transpose());
        const double cut = object_cutoff();  // the running minimum may have dropped within the group
        double d_obj = objects_near
                           ? scene.distance_unmerged(x, nullptr, cut, s.exclude_mask | geometry::SceneSdf::kTableBit)
                           : cap;
        if (d_obj >= cut) d_obj = cap;  // beyond the cutoff: as the cap would read (it changes nothing)
        const double d_table =
            !scene.has_table() ? inf : (table_near ? scene.distance_unmerged(x, nullptr, cap, all_objects) : cap);
        m.min_clearance = std::min(m.min_clearance, d_obj);
        step_min = std::min(step_min, d_obj);
        m.min_table_clearance = std::min(m.min_table_clearance, d_table);
        table_free = table_free && d_table >= table_need;
        const double d = std::min(d_obj, d_table);
        if (d < s.collision_padding) m.collision += chomp_cost(d, s.epsilon, nullptr);
      }
    }
    transit_free = transit_free && step_min >= need;
    if (stop_at_failure && !(transit_free && table_free && target_free))
      return m;  // collision_free, success stay false
  }
  m.collision_free = transit_free && table_free && target_free;
  m.success = m.collision_free && m.smoothness < s.smoothness_threshold;
  return m;
}

}  // namespace pickplan::omg
