#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "pickplan/core/errors.hpp"
#include "pickplan/core/robot.hpp"

using namespace pickplan::core;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R) {
  Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

Eigen::VectorXd random_q(const Robot& r, std::mt19937& rng) {
  Eigen::VectorXd q(r.dof());
  for (int j = 0; j < r.dof(); ++j) {
    double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

}  // namespace

TEST(Robot, TwoLinkPosesMatchHandComputation) {
  Robot r = Robot::from_urdf_file(kData + "/two_link.urdf");
  ASSERT_EQ(r.dof(), 2);
  ASSERT_EQ(r.num_links(), 4);
  EXPECT_EQ(r.joint_names()[0], "shoulder");
  EXPECT_DOUBLE_EQ(r.upper_limits()[1], 2.0);
  EXPECT_DOUBLE_EQ(r.velocity_limits()[1], 3.0);
  RobotWorkspace ws(r);
  const double a = 0.7, b = -1.1;
  const double q[2] = {a, b};
  r.forward_kinematics(q, ws);
  const Eigen::Vector3d tip = ws.link_pose[r.link_index("tip")].p;
  EXPECT_NEAR(tip.x(), std::cos(a) + 0.5 * std::cos(a + b), 1e-14);
  EXPECT_NEAR(tip.y(), std::sin(a) + 0.5 * std::sin(a + b), 1e-14);
  EXPECT_NEAR(tip.z(), 0.2, 1e-14);
  const Eigen::Matrix3d R = ws.link_pose[r.link_index("tip")].R;
  EXPECT_NEAR(R(0, 0), std::cos(a + b), 1e-14);
  EXPECT_NEAR(R(1, 0), std::sin(a + b), 1e-14);
  // Closed-form planar Jacobian of the tip.
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, 2);
  r.point_jacobian(ws, r.link_index("tip"), Eigen::Vector3d::Zero(), J);
  EXPECT_NEAR(J(0, 0), -std::sin(a) - 0.5 * std::sin(a + b), 1e-14);
  EXPECT_NEAR(J(1, 0), std::cos(a) + 0.5 * std::cos(a + b), 1e-14);
  EXPECT_NEAR(J(0, 1), -0.5 * std::sin(a + b), 1e-14);
  EXPECT_NEAR(J(1, 1), 0.5 * std::cos(a + b), 1e-14);
  EXPECT_NEAR(J(5, 0), 1.0, 1e-14);
  EXPECT_NEAR(J(5, 1), 1.0, 1e-14);
}

TEST(Robot, JacobiansMatchCentralFiniteDifferences) {
  Robot r = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  ASSERT_EQ(r.dof(), 5);
  std::mt19937 rng(42);
  const double h = 1e-6;
  RobotWorkspace ws(r), wp(r), wm(r);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, r.dof());
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jx(3, r.dof());
  for (int trial = 0; trial < 200; ++trial) {
    Eigen::VectorXd q = random_q(r, rng);
    r.forward_kinematics(q.data(), ws);
    for (int l = 0; l < r.num_links(); ++l) {
      Eigen::Vector3d p = Eigen::Vector3d::Random() * 0.2;
      r.point_jacobian(ws, l, p, J);
      r.position_jacobian_world(ws, l, ws.link_pose[l].apply(p), Jx);
      EXPECT_LT((J.topRows<3>() - Jx).cwiseAbs().maxCoeff(), 1e-14);
      for (int k = 0; k < r.dof(); ++k) {
        Eigen::VectorXd qp = q, qm = q;
        qp[k] += h;
        qm[k] -= h;
        r.forward_kinematics(qp.data(), wp);
        r.forward_kinematics(qm.data(), wm);
        Eigen::Vector3d dx = (wp.link_pose[l].apply(p) - wm.link_pose[l].apply(p)) / (2 * h);
        Eigen::Vector3d dw = (rotation_log(wp.link_pose[l].R * ws.link_pose[l].R.transpose()) -
                              rotation_log(wm.link_pose[l].R * ws.link_pose[l].R.transpose())) /
                             (2 * h);
        EXPECT_NEAR((J.block<3, 1>(0, k) - dx).norm(), 0.0, 1e-8) << "link " << l << " q " << k;
        EXPECT_NEAR((J.block<3, 1>(3, k) - dw).norm(), 0.0, 1e-8) << "link " << l << " q " << k;
        if (!r.moves(k, l)) EXPECT_EQ(J.col(k).norm(), 0.0);
      }
    }
  }
}

TEST(Robot, BaseTransformComposesWithEveryLink) {
  Robot r = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  Transform base;
  base.R = axis_angle(Eigen::Vector3d(1, 2, 3).normalized(), 0.8);
  base.p = Eigen::Vector3d(0.3, -0.1, 0.7);
  Robot moved = r.with_base(base);
  RobotWorkspace w0(r), w1(moved);
  Eigen::VectorXd q = Eigen::VectorXd::Constant(r.dof(), 0.3);
  r.forward_kinematics(q.data(), w0);
  moved.forward_kinematics(q.data(), w1);
  for (int l = 0; l < r.num_links(); ++l)
    EXPECT_LT(((base * w0.link_pose[l]).matrix() - w1.link_pose[l].matrix()).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(Robot, CollisionPrimitivesAreRead) {
  Robot r = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  const Link& l1 = r.link(r.link_index("l1"));
  ASSERT_EQ(l1.collisions.size(), 1u);
  EXPECT_EQ(l1.collisions[0].kind, CollisionGeometry::Kind::Cylinder);
  EXPECT_DOUBLE_EQ(l1.collisions[0].size.x(), 0.05);
  EXPECT_DOUBLE_EQ(l1.collisions[0].origin.p.z(), 0.1);
  EXPECT_TRUE(std::isinf(r.upper_limits()[r.link(r.link_index("l3")).q_index]));  // continuous joint
}

TEST(Robot, BadInputThrowsClearErrors) {
  EXPECT_THROW(Robot::from_urdf_file(kData + "/does_not_exist.urdf"), FileNotFound);
  EXPECT_THROW(Robot::from_urdf_string("<robot name='x'><link name='a'/><joint name='j'", ".", {}),
               std::invalid_argument);
  EXPECT_THROW(Robot::from_urdf_string(
                   "<robot name='x'><link name='a'><collision><geometry><mesh filename='ghost.stl'/></geometry>"
                   "</collision></link></robot>",
                   kData, {}),
               FileNotFound);
  Robot r = Robot::from_urdf_file(kData + "/two_link.urdf");
  try {
    const double q[1] = {0.0};
    r.check_configuration(q, 1);
    FAIL() << "expected an exception";
  } catch (const std::invalid_argument& e) {
    EXPECT_STREQ(e.what(), "configuration: expected 2 joint values, got 1");
  }
  const double nan_q[2] = {0.0, std::nan("")};
  EXPECT_THROW(r.check_configuration(nan_q, 2), std::invalid_argument);
  EXPECT_THROW(r.link_index("nope"), std::invalid_argument);
}
