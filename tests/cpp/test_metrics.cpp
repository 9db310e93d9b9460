// The paper's trajectory metrics (OMG Sec. IV-A) against closed forms on hand-made trajectories of
// a single body point: the floating hand's origin sits exactly at (q0, q1, q2), the table's distance
// is analytic and a box face's SDF is exact (trilinear interpolation of a plane's distance).
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "mesh_fixtures.hpp"
#include "pickplan/omg/metrics.hpp"

using namespace pickplan;

namespace {

constexpr int kWaypoints = 10;  // dt = 0.1 s

struct PointCase {
  std::shared_ptr<const Robot> robot = test::floating_hand();
  std::shared_ptr<SceneSdf> scene = std::make_shared<SceneSdf>();
  BodyPoints body;
  PointCase() {
    body.link = {robot->link_index("hand")};
    body.points = Vertices::Zero(1, 3);
  }
  ChompProblem problem() const {
    ChompSettings s;
    s.n = kWaypoints;
    s.duration = 1.0;
    return ChompProblem(robot, scene, body, s);
  }
};

Eigen::VectorXd at(double x, double y, double z) {
  Eigen::VectorXd q = Eigen::VectorXd::Zero(6);
  q << x, y, z, 0, 0, 0;
  return q;
}

// Waypoints 1..n of the straight path a -> b (the start a is q0, not a row).
Trajectory line(const Eigen::VectorXd& a, const Eigen::VectorXd& b) {
  Trajectory xi(kWaypoints, a.size());
  for (int t = 0; t < kWaypoints; ++t) xi.row(t) = (a + (b - a) * double(t + 1) / kWaypoints).transpose();
  return xi;
}

double chomp_c(double d, double eps) { return d < 0 ? -d + eps / 2 : (d < eps ? 0.5 * (d - eps) * (d - eps) / eps : 0.0); }

void add_table(SceneSdf& scene) {  // top face at z = 0
  Transform pose;
  pose.p = Eigen::Vector3d(0, 0, -0.05);
  scene.set_table(Eigen::Vector3d(4, 4, 0.1), pose);
}

}  // namespace

TEST(Metrics, InterpolateIsPiecewiseLinearThroughTheWaypoints) {
  const Eigen::VectorXd q0 = at(0, 0, 0);
  Trajectory xi(3, 6);
  xi.row(0) = at(1, 0, 0).transpose();
  xi.row(1) = at(1, 2, 0).transpose();
  xi.row(2) = at(1, 2, -4).transpose();
  const Trajectory same = interpolate(q0, xi, 4);
  EXPECT_EQ(same.row(0), q0.transpose());
  EXPECT_EQ(same.bottomRows(3), xi);
  const Trajectory dense = interpolate(q0, xi, 7);
  EXPECT_LT((dense.row(1) - at(0.5, 0, 0).transpose()).norm(), 1e-15);
  EXPECT_LT((dense.row(3) - at(1, 1, 0).transpose()).norm(), 1e-15);
  EXPECT_LT((dense.row(5) - at(1, 2, -2).transpose()).norm(), 1e-15);
  EXPECT_EQ(dense.row(6), xi.row(2));
}

TEST(Metrics, SmoothnessAndCollisionAtConstantHeightAboveTheTable) {
  PointCase c;
  add_table(*c.scene);
  const ChompProblem p = c.problem();
  const double h = 0.03;
  const Eigen::VectorXd q0 = at(0, 0, h), q1 = at(0.5, 0, h);
  MetricSettings s;
  s.steps = 21;
  const TrajectoryMetrics m = evaluate_trajectory(p, q0, line(q0, q1), s);
  // f_prior of n equal steps: |q1 - q0|^2 / (2 n dt^2).
  EXPECT_NEAR(m.smoothness, 0.25 / (2 * kWaypoints * 0.01), 1e-12);
  EXPECT_NEAR(m.collision, s.steps * chomp_c(h, s.epsilon), 1e-12);
  EXPECT_NEAR(m.min_table_clearance, h, 1e-12);
  EXPECT_NEAR(m.min_clearance, s.epsilon, 1e-12);  // no objects: the cap, max(epsilon, clearances)
  EXPECT_TRUE(m.collision_free);
  EXPECT_TRUE(m.success);
  s.table_clearance = 0.05;
  EXPECT_FALSE(evaluate_trajectory(p, q0, line(q0, q1), s).collision_free);
  s.table_clearance = 0.0;
  s.smoothness_threshold = 1.0;  // 1.25 is not smooth enough
  const TrajectoryMetrics rough = evaluate_trajectory(p, q0, line(q0, q1), s);
  EXPECT_TRUE(rough.collision_free);
  EXPECT_FALSE(rough.success);
}

TEST(Metrics, CollisionSumsTheCostOfEveryDenseStepBelowThePadding) {
  PointCase c;
  add_table(*c.scene);
  const ChompProblem p = c.problem();
  const Eigen::VectorXd q0 = at(0, 0, 0.01), q1 = at(0, 0, 0.1);
  MetricSettings s;
  s.steps = 31;
  double expected = 0;
  for (int k = 0; k < s.steps; ++k) {
    const double z = 0.01 + 0.09 * k / (s.steps - 1);
    if (z < s.collision_padding) expected += chomp_c(z, s.epsilon);
  }
  const TrajectoryMetrics m = evaluate_trajectory(p, q0, line(q0, q1), s);
  EXPECT_NEAR(m.collision, expected, 1e-12);
  EXPECT_NEAR(m.min_table_clearance, 0.01, 1e-12);
  EXPECT_NEAR(m.smoothness, 0.09 * 0.09 / (2 * kWaypoints * 0.01), 1e-12);
}

TEST(Metrics, ObjectClearanceAndTheApproachTail) {
  // The point moves along x at z = 0.3 toward a 0.1 m box centred at (0.5, 0, 0.3): it ends 0.05 m
  // from the face x = 0.45, which it comes closer to than 0.08 m only on the last segment.
  PointCase c;
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d::Constant(0.1), V, F);
  Transform pose;
  pose.p = Eigen::Vector3d(0.5, 0, 0.3);
  c.scene->add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.1})), pose);
  const ChompProblem p = c.problem();
  const Eigen::VectorXd q0 = at(0, 0, 0.3), q1 = at(0.4, 0, 0.3);
  MetricSettings s;
  s.clearance = 0.08;
  const TrajectoryMetrics m = evaluate_trajectory(p, q0, line(q0, q1), s);
  EXPECT_NEAR(m.min_clearance, 0.05, 1e-6);  // grid values are floats
  EXPECT_FALSE(m.collision_free);
  s.tail_waypoints = 2;  // the last two waypoints are the approach: 0.01 m is enough there
  EXPECT_TRUE(evaluate_trajectory(p, q0, line(q0, q1), s).collision_free);
  s.exclude_mask = 1;  // the box is the target: not measured
  EXPECT_NEAR(evaluate_trajectory(p, q0, line(q0, q1), s).min_clearance, 0.2, 1e-12);
  RobotWorkspace ws(*c.robot);
  EXPECT_NEAR(object_clearance(p, q1.data(), 0, 1.0, ws), 0.05, 1e-6);
  EXPECT_NEAR(object_clearance(p, at(0.3, 0, 0.3).data(), 0, 1.0, ws), 0.15, 1e-6);  // outside the grid
  EXPECT_EQ(object_clearance(p, q1.data(), 1, 1.0, ws), 1.0);
}

TEST(Metrics, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  PointCase c;
  const ChompProblem p = c.problem();
  const Eigen::VectorXd q0 = at(0, 0, 0.3), q1 = at(0.4, 0, 0.3);
  const Trajectory xi = line(q0, q1);
  expect_invalid_argument([&] { evaluate_trajectory(p, q0, xi.topRows(9), {}); }, "expected shape (10, 6), got (9, 6)");
  expect_invalid_argument([&] { evaluate_trajectory(p, q0.head(5), xi, {}); }, "expected 6 joint values, got 5");
  expect_invalid_argument([&] { interpolate(q0, xi.leftCols(5), 20); },
                          "trajectory columns: expected 6 joint values (the size of q0), got 5");
  expect_invalid_argument([&] { interpolate(q0, xi, 1); }, "steps must be >= 2, got 1");
  expect_invalid_argument([&] { interpolate(q0, Trajectory(0, 6), 5); }, "no waypoints");
}
