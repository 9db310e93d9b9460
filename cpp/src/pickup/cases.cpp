#include "pickplan/pickup/cases.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "pickplan/core/errors.hpp"

namespace pickplan::pickup {

RhoPoly example_rho(double shift) {
  RhoPoly r;
  r.coeffs.resize(4, 3);
  r.coeffs << 0.995, 0.998, 0.999, 0.95, 0.965, 0.975, 0.85, 0.88, 0.90, 0.60, 0.65, 0.70;
  r.coeffs = (r.coeffs.array() + shift).cwiseMax(0.0).cwiseMin(1.0).matrix();
  r.sg_lo = 0.05;
  r.sg_hi = 1.2;
  r.sc_lo = 0.05;
  r.sc_hi = 0.15;
  return r;
}

void set_part_grasp(PickupProblem& pb, GraspKind kind, double yaw, const Eigen::Vector3d& position) {
  if (!std::isfinite(yaw) || !position.allFinite())
    throw std::invalid_argument("part grasp: yaw and position must be finite");
  const Eigen::Vector3d px(std::cos(yaw), std::sin(yaw), 0.0), py(-std::sin(yaw), std::cos(yaw), 0.0);
  Eigen::Matrix3d R;
  const Eigen::Vector3d z = kind == GraspKind::top ? Eigen::Vector3d(0, 0, -1) : px;
  R.col(2) = z;
  R.col(1) = py;
  R.col(0) = py.cross(z);
  pb.grasp_pose.R = R;
  pb.grasp_pose.p = position;
  pb.approach_dir = px;
  pb.part_xy = position.head<2>();
}

PickupProblem paper_case(const core::Robot& robot, int case_id, const RhoPoly& rho, const PaperCaseOptions& opt) {
  if (case_id < 1 || case_id > 6) throw std::invalid_argument("case_id must be 1..6, got " + std::to_string(case_id));
  if (robot.dof() != 9)
    throw std::invalid_argument("paper cases need the 9-DOF mobile_ur5, got " + std::to_string(robot.dof()) + " DOFs");
  const double yaws[6] = {0.0, M_PI / 4, M_PI / 2, 0.0, M_PI / 4, M_PI / 2};
  PickupProblem pb;
  pb.start = Eigen::Vector3d(0.0, 0.0, M_PI / 6);
  pb.goal = Eigen::Vector3d(8.0, 0.0, 0.0);
  pb.goal_tol_pos = 0.5;
  pb.goal_tol_yaw = M_PI / 4;
  pb.arm_start.resize(6);
  pb.arm_start << 0.0, -2.2, 2.0, -1.4, -1.5708, 0.0;
  pb.arm_rate_limits = Eigen::VectorXd::Constant(6, opt.arm_rate);
  pb.rho = rho;
  pb.gamma = opt.gamma;
  pb.tool_link = robot.link_index("tool");
  set_part_grasp(pb, case_id <= 3 ? GraspKind::top : GraspKind::side, yaws[case_id - 1],
                 Eigen::Vector3d(3.0, 4.0, opt.part_z));
  pb.grasp_area_rmin = 0.35;
  pb.grasp_area_rmax = 0.8;
  if (opt.obstacles) {
    pb.obstacles.push_back({Eigen::Vector3d(3.0, 4.0, 0.15), 0.15});  // pedestal
    pb.obstacles.push_back({Eigen::Vector3d(3.0, 4.0, 0.33), 0.06});  // pedestal top (below the part)
    pb.obstacles.push_back({Eigen::Vector3d(5.2, 0.9, 0.3), 0.3});    // pillar beside the route
  }
  const int base = robot.link_index("base_link");
  pb.body_spheres.push_back({base, Eigen::Vector3d(0.0, 0.0, 0.2), 0.3});
  pb.body_spheres.push_back({robot.link_index("upper_arm_link"), Eigen::Vector3d(-0.2125, 0.0, 0.136), 0.08});
  pb.body_spheres.push_back({robot.link_index("forearm_link"), Eigen::Vector3d(-0.196, 0.0, 0.017), 0.07});
  pb.body_spheres.push_back({robot.link_index("wrist_2_link"), Eigen::Vector3d(0.0, 0.0, 0.0), 0.06});
  pb.body_spheres.push_back({robot.link_index("flange"), Eigen::Vector3d(0.0, 0.0, 0.0), 0.05});
  return pb;
}

PickupMetrics evaluate_pickup(const core::Robot& robot, const PickupProblem& pb, const PickupResult& res, int n) {
  if (n < 3) throw std::invalid_argument("evaluate_pickup: need at least 3 samples");
  if (res.x.size() != res.traj.num_coeffs() + 5)
    throw std::invalid_argument("evaluate_pickup: result has no solution vector");
  core::require_size("evaluate_pickup: result trajectory", robot.dof(), res.traj.dof(), "DOFs (the robot's)");
  if (pb.tool_link < 0 || pb.tool_link >= robot.num_links())
    throw std::invalid_argument("evaluate_pickup: tool_link out of range");
  for (const auto& b : pb.body_spheres)
    if (b.link < 0 || b.link >= robot.num_links())
      throw std::invalid_argument("evaluate_pickup: body sphere link out of range");
  PickupMetrics m;
  const int d = robot.dof();
  core::RobotWorkspace ws(robot);
  Eigen::VectorXd q(d), qd(d);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, d);
  res.traj.eval(res.x.data(), res.T2, q.data(), nullptr, nullptr);
  robot.forward_kinematics(q.data(), ws);
  const core::Transform tool = ws.link_pose[pb.tool_link];
  m.pose_error_position = (tool.p - pb.grasp_pose.p).norm();
  m.pose_error_orientation = Eigen::AngleAxisd(pb.grasp_pose.R.transpose() * tool.R).angle();
  m.min_clearance = std::numeric_limits<double>::infinity();
  const double dt = res.T / (n - 1);
  int ng = 0;
  for (int k = 0; k < n; ++k) {
    const double t = k * dt;
    res.traj.eval(res.x.data(), t, q.data(), qd.data(), nullptr);
    const double nh = std::abs(qd[0] * std::sin(q[2]) - qd[1] * std::cos(q[2]));
    m.nonholonomic_mean += nh / n;
    m.nonholonomic_drift += nh * dt * ((k == 0 || k == n - 1) ? 0.5 : 1.0);
    m.nonholonomic_max = std::max(m.nonholonomic_max, nh);
    m.base_speed_max = std::max(m.base_speed_max, std::hypot(qd[0], qd[1]));
    for (int j = 3; j < d; ++j) {
      m.joint_limit_violation =
          std::max({m.joint_limit_violation, robot.lower_limits()[j] - q[j], q[j] - robot.upper_limits()[j]});
      m.joint_rate_max = std::max(m.joint_rate_max, std::abs(qd[j]));
    }
    robot.forward_kinematics(q.data(), ws);
    for (const auto& b : pb.body_spheres)
      for (const auto& o : pb.obstacles)
        m.min_clearance =
            std::min(m.min_clearance, (ws.link_pose[b.link].apply(b.center) - o.center).norm() - b.radius - o.radius);
    if (t >= res.T1 && t <= res.T2) {
      robot.point_jacobian(ws, pb.tool_link, Eigen::Vector3d::Zero(), J);
      const Eigen::Vector3d v = J.topRows<3>() * qd;
      m.velocity_error_max = std::max(m.velocity_error_max, (v - res.S_g * pb.approach_dir).norm());
      m.gripper_speed_grasp_mean += v.norm();
      m.base_speed_grasp_mean += std::hypot(qd[0], qd[1]);
      ++ng;
    }
  }
  if (ng) {
    m.gripper_speed_grasp_mean /= ng;
    m.base_speed_grasp_mean /= ng;
  }
  res.traj.eval(res.x.data(), res.T, q.data(), nullptr, nullptr);
  m.goal_position_error = std::hypot(q[0] - pb.goal[0], q[1] - pb.goal[1]);
  m.success_probability = pb.rho.value(res.S_g, res.S_c);
  return m;
}

}  // namespace pickplan::pickup
