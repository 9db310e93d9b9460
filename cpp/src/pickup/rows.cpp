// Active-set support of the pick-up NLP: which optional rows (joint-position, collision) a stage
// needs near a point, and the dense check (collisions, joint limits, lateral base motion) between
// the regular samples.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "nlp_detail.hpp"
#include "pickplan/core/errors.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {

void PickupRowSubset::merge(const PickupRowSubset& o) {
  for (const auto& j : o.joints)
    if (std::none_of(joints.begin(), joints.end(), [&](const Joint& a) {
          return a.joint == j.joint && a.sample == j.sample &&
                 (j.sample >= 0 || (a.w[0] == j.w[0] && a.w[1] == j.w[1] && a.w[2] == j.w[2]));
        }))
      joints.push_back(j);
  for (const auto& c : o.collisions)
    if (std::none_of(collisions.begin(), collisions.end(), [&](const Collision& a) {
          return a.pair == c.pair && a.sample == c.sample &&
                 (c.sample >= 0 || (a.w[0] == c.w[0] && a.w[1] == c.w[1] && a.w[2] == c.w[2]));
        }))
      collisions.push_back(c);
  for (const auto& n : o.nonholonomic)
    if (std::none_of(nonholonomic.begin(), nonholonomic.end(),
                     [&](const Instant& a) { return a.w[0] == n.w[0] && a.w[1] == n.w[1] && a.w[2] == n.w[2]; }))
      nonholonomic.push_back(n);
}

namespace {
double clearance(const core::RobotWorkspace& ws, const PickupProblem& pb, int pair) {
  const int no = static_cast<int>(pb.obstacles.size());
  const BodySphere& b = pb.body_spheres[pair / no];
  const SphereObstacle& o = pb.obstacles[pair % no];
  return (ws.link_pose[b.link].apply(b.center) - o.center).norm() - b.radius - o.radius;
}
}  // namespace

PickupRowSubset PickupConstraints::near_rows(const Eigen::VectorXd& x, double joint_window,
                                             double collision_window) const {
  core::require_size("NLP variables x", n_, x.size(), "values");
  PickupRowSubset out;
  const int na = dof_ - 3, npairs = static_cast<int>(pb_.obstacles.size() * pb_.body_spheres.size());
  const double s1 = x[idx_s1()], s2 = x[idx_s2()];
  Eigen::VectorXd q(dof_);
  core::RobotWorkspace ws(robot_);
  for (int s = 0; s < nreg_; ++s) {
    const Sample& S = samples_[s];
    traj_.eval(x.data(), S.w[0] * s1 + S.w[1] * s2 + S.w[2], q.data(), nullptr, nullptr);
    for (int j = 0; j < na && s > 0; ++j) {
      const double lo = robot_.lower_limits()[3 + j] + st_.joint_limit_margin;
      const double hi = robot_.upper_limits()[3 + j] - st_.joint_limit_margin;
      if (std::min(q[3 + j] - lo, hi - q[3 + j]) < joint_window) out.joints.push_back({s, j, {0, 0, 0}});
    }
    if (!has_collision_rows()) continue;
    robot_.forward_kinematics(q.data(), ws);
    for (int p = 0; p < npairs; ++p)
      if (pair_in_stage(p) && clearance(ws, pb_, p) - st_.collision_margin < collision_window)
        out.collisions.push_back({s, {0, 0, 0}, p});
  }
  return out;
}

PickupRowSubset PickupConstraints::dense_points(const Eigen::VectorXd& x, int subdivisions, double threshold,
                                                double joint_slack, double* min_clearance) const {
  core::require_size("NLP variables x", n_, x.size(), "values");
  if (subdivisions < 1)
    throw std::invalid_argument("dense check: subdivisions must be >= 1, got " + std::to_string(subdivisions));
  PickupRowSubset out;
  double least = std::numeric_limits<double>::infinity();
  const int na = dof_ - 3, npairs = static_cast<int>(pb_.obstacles.size() * pb_.body_spheres.size());
  const bool coll = has_collision_rows();
  const double s1 = x[idx_s1()], s2 = x[idx_s2()];
  Eigen::VectorXd q(dof_), qs(dof_);
  core::RobotWorkspace ws(robot_);
  std::vector<double> best(npairs), jbest(na);
  std::vector<PickupRowSubset::Collision> at(npairs);
  std::vector<PickupRowSubset::Joint> jat(na);
  for (int g = 0; g + 1 < nreg_ && subdivisions > 1; ++g) {  // gap between regular samples g, g + 1 (time order)
    const Sample &A = samples_[g], &B = samples_[g + 1];
    std::fill(best.begin(), best.end(), std::numeric_limits<double>::infinity());
    std::fill(jbest.begin(), jbest.end(), std::numeric_limits<double>::infinity());
    double lateral = st_.dense_nonholonomic * x[idx_T()];  // the largest lateral motion (d/ds) above it, and where
    PickupRowSubset::Instant nh_at;
    bool nh = false;
    for (int k = 1; k < subdivisions; ++k) {  // interior instants
      const double f = double(k) / subdivisions;
      const double w[3] = {A.w[0] + f * (B.w[0] - A.w[0]), A.w[1] + f * (B.w[1] - A.w[1]),
                           A.w[2] + f * (B.w[2] - A.w[2])};
      traj_.eval(x.data(), w[0] * s1 + w[1] * s2 + w[2], q.data(), qs.data(), nullptr);  // qs: d/ds (traj_ has T = 1)
      const double lat = std::abs(qs[0] * std::sin(q[2]) - qs[1] * std::cos(q[2]));      // the row K_NH's value
      if (st_.dense_nonholonomic > 0 && lat > lateral) {
        lateral = lat;
        nh_at = {{w[0], w[1], w[2]}};
        nh = true;
      }
      for (int j = 0; j < na; ++j) {  // slack to the real limit
        const double slack = std::min(q[3 + j] - robot_.lower_limits()[3 + j], robot_.upper_limits()[3 + j] - q[3 + j]);
        if (slack < jbest[j]) {
          jbest[j] = slack;
          jat[j] = {-1, j, {w[0], w[1], w[2]}};
        }
      }
      if (!coll) continue;
      robot_.forward_kinematics(q.data(), ws);
      for (int p = 0; p < npairs; ++p) {
        if (!pair_in_stage(p)) continue;
        const double c = clearance(ws, pb_, p);
        least = std::min(least, c);
        if (c < best[p]) {
          best[p] = c;
          at[p] = {-1, {w[0], w[1], w[2]}, p};
        }
      }
    }
    for (int p = 0; p < npairs; ++p)
      if (best[p] < threshold) out.collisions.push_back(at[p]);
    for (int j = 0; j < na; ++j)
      if (jbest[j] < st_.joint_limit_margin - joint_slack) out.joints.push_back(jat[j]);
    if (nh) out.nonholonomic.push_back(nh_at);
  }
  if (min_clearance) {
    if (coll)  // the regular samples too
      for (int s = 0; s < nreg_; ++s) {
        const Sample& S = samples_[s];
        traj_.eval(x.data(), S.w[0] * s1 + S.w[1] * s2 + S.w[2], q.data(), nullptr, nullptr);
        robot_.forward_kinematics(q.data(), ws);
        for (int p = 0; p < npairs; ++p)
          if (pair_in_stage(p)) least = std::min(least, clearance(ws, pb_, p));
      }
    *min_clearance = least;
  }
  return out;
}

}  // namespace pickplan::pickup
