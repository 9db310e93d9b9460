// The paper's trajectory metrics (OMG Sec. IV-A) against closed forms on hand-made trajectories of
// a single body point: the floating hand's origin sits exactly at (q0, q1, q2), the table's distance
// is analytic and a box face's SDF is exact (trilinear interpolation of a plane's distance).
#include <algorithm>
#include <cmath>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "mesh_fixtures.hpp"
#include "pickplan/omg/metrics.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;

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

double chomp_c(double d, double eps) {
  return d < 0 ? -d + eps / 2 : (d < eps ? 0.5 * (d - eps) * (d - eps) / eps : 0.0);
}

void add_table(SceneSdf& scene) {  // top face at z = 0
  Transform pose;
  pose.p = Eigen::Vector3d(0, 0, -0.05);
  scene.set_table(Eigen::Vector3d(4, 4, 0.1), pose);
}

void add_box(SceneSdf& scene) {  // a 0.1 m box centred at (0.5, 0, 0.3)
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d::Constant(0.1), V, F);
  Transform pose;
  pose.p = Eigen::Vector3d(0.5, 0, 0.3);
  scene.add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.1})), pose);
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
  add_box(*c.scene);
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

TEST(Metrics, TheTransitKeepsItsClearanceFromTheTargetWhenAsked) {
  // The target (excluded, a 0.1 m box centred at (0.5, 0, 0.3), top face z = 0.35) lies on the transit
  // along x at z = 0.33 (through it) and 0.02 m below the one at z = 0.37; the tail is not measured.
  PointCase c;
  add_box(*c.scene);
  const ChompProblem p = c.problem();
  MetricSettings s;
  s.exclude_mask = 1;
  s.tail_waypoints = 2;
  const Eigen::VectorXd through0 = at(0.2, 0, 0.33), through1 = at(1.0, 0, 0.33);
  const Eigen::VectorXd above0 = at(0.2, 0, 0.37), above1 = at(1.0, 0, 0.37);
  EXPECT_TRUE(evaluate_trajectory(p, through0, line(through0, through1), s).collision_free);  // the paper's test
  s.transit_target_clearance = 0.0;
  EXPECT_FALSE(evaluate_trajectory(p, through0, line(through0, through1), s).collision_free);
  EXPECT_FALSE(evaluate_trajectory(p, through0, line(through0, through1), s, true).collision_free);
  EXPECT_TRUE(evaluate_trajectory(p, above0, line(above0, above1), s).collision_free);
  s.transit_target_clearance = 0.01;
  EXPECT_TRUE(evaluate_trajectory(p, above0, line(above0, above1), s).collision_free);
  s.transit_target_clearance = 0.03;  // 0.02 m above the top is not enough
  EXPECT_FALSE(evaluate_trajectory(p, above0, line(above0, above1), s).collision_free);
  // Only the tail reaches the target (the pre-grasp, waypoint 8, is 0.13 m before its face): the approach's.
  const Eigen::VectorXd far0 = at(-0.4, 0, 0.33), near1 = at(0.5, 0, 0.33);
  s.tail_waypoints = 3;
  EXPECT_TRUE(evaluate_trajectory(p, far0, line(far0, near1), s).collision_free);
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

// The success test skips links by bounds and points beyond the running cutoff (issue 24); against a
// brute force that measures every body point at every dense step up to the cap, the metrics are
// equal (bit for bit: skipped points add exactly nothing), and stop_at_failure gives the same verdict.
TEST(Metrics, CullingAndCutoffsEqualMeasuringEveryPoint) {
  auto robot = test::mobile_two_link();
  auto scene = std::make_shared<SceneSdf>();
  add_table(*scene);
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d(0.1, 0.1, 0.3), V, F);
  const auto grid = std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.2}));
  for (const Eigen::Vector3d& at :
       {Eigen::Vector3d(0.9, 0.3, 0.15), Eigen::Vector3d(-0.2, 0.8, 0.15), Eigen::Vector3d(0.5, -0.6, 0.15)}) {
    Transform pose;
    pose.p = at;
    scene->add_object(grid, pose);
  }
  BodyPoints body;
  const int links[] = {robot->link_index("upper"), robot->link_index("fore"), robot->link_index("tool")};
  for (int l : links)
    for (int k = 0; k < 8; ++k) {
      body.link.push_back(l);
      body.points.conservativeResize(body.link.size(), 3);
      body.points.row(body.link.size() - 1) = Eigen::RowVector3d(0.05 * k, 0.01 * (k % 2), -0.12 * (k % 3));
    }
  ChompSettings cs;
  cs.n = kWaypoints;
  const ChompProblem p(robot, scene, body, cs);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.5, 1.5);
  int successes = 0, failures = 0;
  // Per-object bounds first; then with merged grids for both target masks (the bounds read from them).
  for (int trial = 0; trial < 80; ++trial) {
    if (trial == 40) {
      scene->merge(0);
      scene->merge(1);
      rng.seed(3);  // the same trajectories again
    }
    Eigen::VectorXd q0(5), q1(5);
    for (int j = 0; j < 5; ++j) q0[j] = 0.3 * u(rng), q1[j] = u(rng);
    q0.head<2>() *= 0.2;
    q1.head<2>() *= 0.2;
    MetricSettings s;
    s.steps = 60;
    s.exclude_mask = trial % 4 == 0 ? 1 : 0;  // sometimes the first box is the target
    s.tail_waypoints = trial % 3;
    s.clearance = 0.05 + 0.01 * (trial % 5);
    const Trajectory xi = line(q0, q1);
    const TrajectoryMetrics m = evaluate_trajectory(p, q0, xi, s);
    // brute force: every point, every step, both parts up to the cap
    const double cap = std::max({s.epsilon, s.clearance, s.tail_clearance, s.collision_padding, s.table_clearance});
    const Trajectory dense = interpolate(q0, xi, s.steps);
    RobotWorkspace ws(*robot);
    double min_obj = cap, min_table = cap, collision = 0;
    bool free = true;
    const double tail_start =
        s.tail_waypoints > 0 ? double(kWaypoints - s.tail_waypoints) / kWaypoints * (s.steps - 1) : s.steps;
    for (int t = 0; t < dense.rows(); ++t) {
      robot->forward_kinematics(dense.row(t).data(), ws);
      for (int k = 0; k < body.size(); ++k) {
        const Eigen::Vector3d x = ws.link_pose[body.link[k]].apply(body.points.row(k).transpose());
        const double d_obj = scene->distance_unmerged(x, nullptr, cap, s.exclude_mask | SceneSdf::kTableBit);
        const double d_table = scene->distance_unmerged(x, nullptr, cap, 7);
        min_obj = std::min(min_obj, d_obj);
        min_table = std::min(min_table, d_table);
        free = free && d_obj >= (t >= tail_start ? s.tail_clearance : s.clearance) && d_table >= s.table_clearance;
        if (std::min(d_obj, d_table) < s.collision_padding) collision += chomp_c(std::min(d_obj, d_table), s.epsilon);
      }
    }
    EXPECT_EQ(m.min_clearance, min_obj) << trial;
    EXPECT_EQ(m.min_table_clearance, min_table) << trial;
    EXPECT_EQ(m.collision, collision) << trial;
    EXPECT_EQ(m.collision_free, free) << trial;
    EXPECT_EQ(evaluate_trajectory(p, q0, xi, s, /*stop_at_failure=*/true).success, m.success) << trial;
    (m.success ? successes : failures)++;
  }
  EXPECT_GT(successes, 3);  // both verdicts occur
  EXPECT_GT(failures, 3);
}
