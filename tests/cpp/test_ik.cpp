// The damped-least-squares IK (core/ik.hpp) against independent truth: forward kinematics of the
// solution, the planar two-link arm's closed form, a finite-difference Jacobian, the joint limits.
#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "pickplan/core/ik.hpp"
#include "pickplan/core/robot.hpp"
#include "pickup_fixtures.hpp"

using namespace pickplan::core;
namespace test = pickplan::test;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;
constexpr int kBaseJoints = 3;  // mobile UR5: base x, y, yaw, then the six arm joints

Robot two_link() { return Robot::from_urdf_file(kData + "/two_link.urdf"); }

Eigen::VectorXd random_q(const Robot& r, std::mt19937& rng, double inset = 0.0) {
  Eigen::VectorXd q(r.dof());
  for (int j = 0; j < r.dof(); ++j) {
    const double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    const double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = std::uniform_real_distribution<double>(lo + inset, hi - inset)(rng);
  }
  return q;
}

Transform link_pose(const Robot& r, const Eigen::VectorXd& q, int link) {
  RobotWorkspace ws(r);
  r.forward_kinematics(q.data(), ws);
  return ws.link_pose[link];
}

// Position error (m) and rotation angle (rad, from the trace) between two poses.
std::pair<double, double> distance(const Transform& a, const Transform& b) {
  const double c = std::clamp(((a.R.transpose() * b.R).trace() - 1.0) / 2.0, -1.0, 1.0);
  return {(a.p - b.p).norm(), std::acos(c)};
}

bool within_limits(const Robot& r, const Eigen::VectorXd& q, double margin = 0.0) {
  for (int j = 0; j < r.dof(); ++j)
    if (q[j] < r.lower_limits()[j] + margin - 1e-12 || q[j] > r.upper_limits()[j] - margin + 1e-12) return false;
  return true;
}

std::vector<double> arm_only(const Robot& r) {
  std::vector<double> w(r.dof(), 1.0);
  for (int j = 0; j < kBaseJoints; ++j) w[j] = 0.0;
  return w;
}

// The mobile UR5's tool with the base frozen: the pick-up seeds' arm IK.
struct Ur5Arm {
  std::shared_ptr<const Robot> robot = std::make_shared<const Robot>(test::load_mobile_ur5());
  int tool = robot->link_index("tool");
  IkSettings settings = with_weights(arm_only(*robot));
  IkSolver solver() const { return IkSolver(robot, tool, settings); }

  static IkSettings with_weights(std::vector<double> weights) {
    IkSettings s;
    s.weights = std::move(weights);
    return s;
  }
};

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "(no std::invalid_argument)";
}

}  // namespace

// 200 poses of the UR5's tool from FK of random configurations: the multi-start solver reaches
// almost all; FK of every converged solution reproduces the pose, inside the limits, base frozen.
TEST(Ik, ReachesRandomReachablePoses) {
  const Ur5Arm arm;
  const IkSolver ik = arm.solver();
  std::mt19937 rng(7);
  const Eigen::VectorXd start = random_q(*arm.robot, rng);
  int converged = 0;
  const int n = 200;
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd q_true = random_q(*arm.robot, rng, 0.1);
    q_true.head<kBaseJoints>() = start.head<kBaseJoints>();
    const Transform target = link_pose(*arm.robot, q_true, arm.tool);
    const IkSolution sol = ik.solve_any(target, start);
    EXPECT_TRUE(within_limits(*arm.robot, sol.q));
    EXPECT_EQ(sol.q.head<kBaseJoints>(), start.head<kBaseJoints>());
    if (!sol.converged) continue;
    ++converged;
    const auto [dp, dr] = distance(link_pose(*arm.robot, sol.q, arm.tool), target);
    EXPECT_LT(dp, arm.settings.position_tolerance);
    EXPECT_LT(dr, 1.01 * arm.settings.rotation_tolerance);
    EXPECT_NEAR(dp, sol.position_error, 1e-12);
  }
  EXPECT_GE(converged, 0.97 * n);
}

// Position only, planar two-link arm (lengths 1 and 0.5): the elbow angle of any solution is the
// closed form's, |q2| = acos((d^2 - 1 - 0.25) / (2 * 1 * 0.5)).
TEST(Ik, PositionTaskMatchesTheTwoLinkClosedForm) {
  const Robot r = two_link();
  const int tip = r.link_index("tip");
  DlsSettings s;
  s.task = IkTask::position;
  s.position_tolerance = 1e-9;
  s.max_iterations = 200;
  std::mt19937 rng(3);
  for (int i = 0; i < 50; ++i) {
    const Eigen::VectorXd q_true = random_q(r, rng, 0.2);
    Transform target = link_pose(r, q_true, tip);
    target.R = Eigen::AngleAxisd(1.0, Eigen::Vector3d::UnitX()).toRotationMatrix();  // unreachable, ignored
    const Eigen::VectorXd seed =
        (q_true + Eigen::Vector2d(0.3, -0.3)).cwiseMax(r.lower_limits()).cwiseMin(r.upper_limits());
    const IkSolution sol = solve_ik(r, tip, Transform{}, target, seed, s);
    ASSERT_TRUE(sol.converged) << i;
    const double d = std::hypot(target.p.x(), target.p.y());
    EXPECT_NEAR(std::abs(sol.q[1]), std::acos((d * d - 1.25) / 1.0), 1e-6);
    EXPECT_LT((link_pose(r, sol.q, tip).p - target.p).norm(), 1e-9);
  }
}

// One step with max_iterations 1 is dq = W J^T (J W J^T + lambda I)^-1 e, J here by central
// differences of FK (position, and the rotation vector of R(q + h) R(q)^T).
TEST(Ik, OneWeightedStepIsTheDampedLeastSquaresFormula) {
  const Robot r = test::load_mobile_ur5();
  const int tool = r.link_index("tool");
  std::mt19937 rng(11);
  const Eigen::VectorXd q0 = random_q(r, rng, 0.5);
  Eigen::VectorXd q1 = q0;
  q1.tail(r.dof() - kBaseJoints) += Eigen::VectorXd::Constant(r.dof() - kBaseJoints, 0.05);
  q1[0] += 0.05;
  const Transform target = link_pose(r, q1, tool), T0 = link_pose(r, q0, tool);
  DlsSettings s;
  s.damping_schedule = IkDamping::fixed;
  s.damping = 1e-3;
  s.max_iterations = 1;
  s.max_step = 10.0;
  s.weights = arm_only(r);
  s.weights[0] = s.weights[1] = 0.3;
  const IkSolution sol = solve_ik(r, tool, Transform{}, target, q0, s);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, r.dof());
  const double h = 1e-6;
  for (int j = 0; j < r.dof(); ++j) {
    Eigen::VectorXd qp = q0, qm = q0;
    qp[j] += h;
    qm[j] -= h;
    const Transform Tp = link_pose(r, qp, tool), Tm = link_pose(r, qm, tool);
    J.col(j).head<3>() = (Tp.p - Tm.p) / (2 * h);
    J.col(j).tail<3>() = rotation_log(Tp.R * Tm.R.transpose()) / (2 * h);
  }
  Eigen::Matrix<double, 6, 1> e;
  e.head<3>() = target.p - T0.p;
  e.tail<3>() = rotation_log(target.R * T0.R.transpose());
  const Eigen::VectorXd W = Eigen::Map<const Eigen::VectorXd>(s.weights.data(), r.dof());
  const Eigen::Matrix<double, 6, 6> A =
      J * W.asDiagonal() * J.transpose() + s.damping * Eigen::Matrix<double, 6, 6>::Identity();
  const Eigen::VectorXd dq = W.asDiagonal() * J.transpose() * A.ldlt().solve(e);
  EXPECT_EQ(sol.iterations, 1);
  EXPECT_LT((sol.q - q0 - dq).cwiseAbs().maxCoeff(), 1e-6);
  EXPECT_EQ(sol.q[2], q0[2]);  // weight 0: the heading never moves
}

// A weight of zero freezes a joint at the seed's value, even a seed outside its limits, while the
// others still reach a target that the frozen value allows.
TEST(Ik, ZeroWeightFreezesAJoint) {
  Ur5Arm arm;
  const auto& r = arm.robot;
  const int tool = arm.tool, pan = kBaseJoints;
  arm.settings.weights[pan] = 0.0;
  arm.settings.task = IkTask::position;  // five joints left: any position, not any pose
  const IkSolver ik = arm.solver();
  std::mt19937 rng(5);
  for (int i = 0; i < 20; ++i) {
    const Eigen::VectorXd q_true = random_q(*r, rng, 0.1);
    Eigen::VectorXd start = random_q(*r, rng, 0.1);
    start.head(pan + 1) = q_true.head(pan + 1);
    if (i == 0) start[pan] = r->upper_limits()[pan] + 0.5;  // frozen joints are not clamped either
    const Transform target = link_pose(*r, i == 0 ? start : q_true, tool);
    const IkSolution sol = ik.solve_any(target, start);
    EXPECT_EQ(sol.q.head(pan + 1), start.head(pan + 1)) << i;
    EXPECT_TRUE(sol.converged) << i;
  }
}

// Limits with a margin: the two-link elbow is limited to [-2, 2]; a point at the distance only an
// elbow of 2.5 reaches cannot converge, and the descent ends at the limit minus the margin.
TEST(Ik, LimitsAndMarginAreRespected) {
  const Robot r = two_link();
  const int tip = r.link_index("tip");
  Transform target = link_pose(r, Eigen::Vector2d(0.4, 2.5), tip);
  for (IkDamping schedule : {IkDamping::adaptive, IkDamping::fixed}) {
    DlsSettings s;
    s.task = IkTask::position;
    s.damping_schedule = schedule;
    s.limit_margin = 0.1;
    s.max_iterations = 300;
    const IkSolution sol = solve_ik(r, tip, Transform{}, target, Eigen::Vector2d(0.0, 0.5), s);
    EXPECT_FALSE(sol.converged);
    EXPECT_TRUE(within_limits(r, sol.q, s.limit_margin));
    EXPECT_NEAR(sol.q[1], 2.0 - s.limit_margin, 1e-6);
    // No configuration inside the margin gets nearer than the circle the tip draws with the
    // elbow at 1.9 (the target lies inside it); clamped steps settle close to that bound.
    const double bound = std::sqrt(1.25 + std::cos(2.0 - s.limit_margin)) - std::hypot(target.p.x(), target.p.y());
    EXPECT_GE(sol.position_error, bound - 1e-12);
    EXPECT_LT(sol.position_error, bound + 0.02);
  }
}

// A point beyond the arm's reach (1.5 m): no convergence, and the residual is the distance to the
// outstretched arm, |p| - 1.5.
TEST(Ik, UnreachableTargetReportsNonConvergence) {
  const Robot r = two_link();
  const int tip = r.link_index("tip");
  Transform target;
  target.p = Eigen::Vector3d(1.2, 1.2, 0.2);
  for (IkTask task : {IkTask::position, IkTask::pose}) {
    DlsSettings s;
    s.task = task;
    s.max_iterations = 200;
    const IkSolution sol = solve_ik(r, tip, Transform{}, target, Eigen::Vector2d(0.1, 0.3), s);
    EXPECT_FALSE(sol.converged);
    if (task == IkTask::position) EXPECT_NEAR(sol.position_error, std::hypot(1.2, 1.2) - 1.5, 1e-3);
  }
}

// A lift: the tool 10 cm straight up in 10 steps, each solved from the previous one.
TEST(Ik, SolvePathFollowsAStraightLine) {
  const Ur5Arm arm;
  const IkSolver ik = arm.solver();
  std::mt19937 rng(2);
  const Eigen::VectorXd q0 = random_q(*arm.robot, rng, 0.8);
  const Transform T0 = link_pose(*arm.robot, q0, arm.tool);
  std::vector<Transform> targets;
  for (int k = 1; k <= 10; ++k) {
    targets.push_back(T0);
    targets.back().p.z() += 0.01 * k;
  }
  const auto path = ik.solve_path(targets, q0);
  ASSERT_EQ(path.size(), targets.size());
  Eigen::VectorXd prev = q0;
  for (size_t k = 0; k < path.size(); ++k) {
    ASSERT_TRUE(path[k].converged) << k;
    const auto [dp, dr] = distance(link_pose(*arm.robot, path[k].q, arm.tool), targets[k]);
    EXPECT_LT(dp, arm.settings.position_tolerance);
    EXPECT_LT((path[k].q - prev).cwiseAbs().maxCoeff(), 0.2) << k;  // a continuous path, no jump to another branch
    prev = path[k].q;
  }
}

TEST(Ik, BadSizesAndSettingsThrowClearly) {
  auto r = std::make_shared<const Robot>(test::load_mobile_ur5());
  const int tool = r->link_index("tool");
  const Transform target;
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r->dof());
  DlsSettings s;
  EXPECT_EQ(message_of([&] { solve_ik(*r, tool, {}, target, Eigen::VectorXd::Zero(6), s); }),
            "IK seed: expected 9 joint values, got 6");
  s.weights = {1.0, 1.0};
  EXPECT_EQ(message_of([&] { solve_ik(*r, tool, {}, target, q, s); }),
            "IK settings: weights: expected 9 entries (one per joint), got 2");
  s.weights.assign(r->dof(), 1.0);
  s.weights[4] = -1.0;
  EXPECT_NE(message_of([&] { solve_ik(*r, tool, {}, target, q, s); }).find("weights must be finite and >= 0"),
            std::string::npos);
  s.weights.clear();
  s.damping = 0.0;
  EXPECT_NE(message_of([&] { solve_ik(*r, tool, {}, target, q, s); }).find("damping must be > 0"), std::string::npos);
  s = DlsSettings{};
  EXPECT_NE(message_of([&] { solve_ik(*r, r->num_links(), {}, target, q, s); }).find("out of range"),
            std::string::npos);
  Eigen::VectorXd nan_seed = q;
  nan_seed[2] = std::nan("");
  EXPECT_NE(message_of([&] { solve_ik(*r, tool, {}, target, nan_seed, s); }).find("IK seed"), std::string::npos);
  IkSettings bad;
  bad.weights = {1.0};
  EXPECT_NE(message_of([&] { const IkSolver unused(r, tool, bad); }).find("weights: expected 9"), std::string::npos);
  const IkSolver ik(r, tool);
  EXPECT_NE(message_of([&] { ik.solve(target, Eigen::VectorXd::Zero(3)); }).find("expected 9 joint values, got 3"),
            std::string::npos);
}
