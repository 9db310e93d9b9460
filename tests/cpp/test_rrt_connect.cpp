// RRT-Connect, shortcutting and the bounded-motion check, on a floating hand and a wall with a hole.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/omg/rrt_connect.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;
using pickplan::test::floating_hand;

namespace {

Transform at(const Eigen::Vector3d& p) {
  Transform T;
  T.p = p;
  return T;
}

SceneObject solid(const std::string& name, const Eigen::Vector3d& size, const Eigen::Vector3d& centre) {
  return {name, TriangleMesh{}, at(centre), std::make_shared<const CollisionShape>(Primitive::box(size), name)};
}

// A wall in the plane x = 0 (2 cm thick) with a 24 cm square hole at y in [-0.12, 0.12], z in [0.18, 0.42].
std::vector<SceneObject> wall_with_hole() {
  return {solid("below", {0.02, 2.0, 0.68}, {0, 0, 0.18 - 0.34}),
          solid("above", {0.02, 2.0, 0.58}, {0, 0, 0.42 + 0.29}),
          solid("left", {0.02, 0.88, 0.24}, {0, 0.12 + 0.44, 0.3}),
          solid("right", {0.02, 0.88, 0.24}, {0, -0.12 - 0.44, 0.3})};
}

CollisionChecker hand_checker(const Robot& r, std::vector<SceneObject> objects) {
  return CollisionChecker(r, {{"hand", link_collision_mesh(r, r.link_index("hand"))}}, std::move(objects));
}

Eigen::VectorXd hand_at(double x, double y, double z, double yaw = 0, double pitch = 0, double roll = 0) {
  Eigen::VectorXd q(6);
  q << x, y, z, yaw, pitch, roll;
  return q;
}

}  // namespace

TEST(MotionBound, BoundsTheMotionOfEveryVertex) {
  auto r = floating_hand();
  CollisionChecker c = hand_checker(*r, {});
  MotionBound bound(c);
  // Prismatic joints move everything by |dq|; the rotations by at most the palm's reach from the origin.
  for (int j = 0; j < 3; ++j) EXPECT_DOUBLE_EQ(bound.factors()[j], 1.0);
  const TriangleMesh palm = link_collision_mesh(*r, r->link_index("hand"));
  double reach = 0;
  for (int v = 0; v < palm.num_vertices(); ++v) reach = std::max(reach, palm.vertices.row(v).norm());
  for (int j = 3; j < 6; ++j) EXPECT_GE(bound.factors()[j], reach - 1e-12);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.8, 0.8);
  RobotWorkspace wa(*r), wb(*r);
  const int hand = r->link_index("hand");
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::VectorXd a = hand_at(u(rng), u(rng), u(rng) * 0.5, u(rng), u(rng), u(rng));
    const Eigen::VectorXd b = a + 0.1 * hand_at(u(rng), u(rng), u(rng), u(rng), u(rng), u(rng));
    r->forward_kinematics(a.data(), wa);
    r->forward_kinematics(b.data(), wb);
    double moved = 0;
    for (int v = 0; v < palm.num_vertices(); ++v) {
      const Eigen::Vector3d x = palm.vertices.row(v).transpose();
      moved = std::max(moved, (wa.link_pose[hand].apply(x) - wb.link_pose[hand].apply(x)).norm());
    }
    EXPECT_LE(moved, bound.bound(a.data(), b.data()) + 1e-12);
  }
}

TEST(RrtConnect, FindsTheHoleAndShortcutsStayValid) {
  auto r = floating_hand();
  CollisionChecker c = hand_checker(*r, wall_with_hole());
  RrtSettings s;
  s.seed = 7;
  s.resolution = 0.005;
  MotionPlanner planner(c, s);
  const Eigen::VectorXd start = hand_at(-0.4, 0.3, 0.7), goal = hand_at(0.4, -0.3, 0.7);
  Trajectory straight(2, 6);
  straight.row(0) = start.transpose();
  straight.row(1) = goal.transpose();
  EXPECT_EQ(planner.first_invalid_segment(straight), 0);  // through the wall
  Trajectory goals(1, 6);
  goals.row(0) = goal.transpose();
  const RrtResult res = planner.rrt_connect(start, goals);
  ASSERT_EQ(res.status, RrtStatus::solved);
  EXPECT_EQ(res.goal, 0);
  EXPECT_TRUE(res.path.row(0).transpose().isApprox(start));
  EXPECT_TRUE(res.path.bottomRows(1).transpose().isApprox(goal));
  EXPECT_EQ(planner.first_invalid_segment(res.path), -1);
  // Every path from x < 0 to x > 0 crosses the wall's plane inside the hole.
  bool through_hole = false;
  for (long i = 0; i + 1 < res.path.rows(); ++i)
    if (res.path(i, 0) < 0 && res.path(i + 1, 0) >= 0) {
      const double t = -res.path(i, 0) / (res.path(i + 1, 0) - res.path(i, 0));
      const Eigen::RowVectorXd x = res.path.row(i) + t * (res.path.row(i + 1) - res.path.row(i));
      through_hole = std::abs(x[1]) < 0.12 && x[2] > 0.18 && x[2] < 0.42;
    }
  EXPECT_TRUE(through_hole);
  const Trajectory short_path = planner.shortcut(res.path, 200, 3);
  EXPECT_EQ(planner.first_invalid_segment(short_path), -1);
  auto length = [](const Trajectory& p) {
    double l = 0;
    for (long i = 0; i + 1 < p.rows(); ++i) l += (p.row(i + 1) - p.row(i)).norm();
    return l;
  };
  EXPECT_LE(length(short_path), length(res.path) + 1e-12);
  EXPECT_TRUE(short_path.row(0).isApprox(res.path.row(0)));
  EXPECT_TRUE(short_path.bottomRows(1).isApprox(res.path.bottomRows(1)));
  // The same seed, the same path.
  EXPECT_TRUE(planner.rrt_connect(start, goals).path.isApprox(res.path));
}

TEST(RrtConnect, GoalSetsAndInvalidEnds) {
  auto r = floating_hand();
  CollisionChecker c = hand_checker(*r, wall_with_hole());
  MotionPlanner planner(c);
  const Eigen::VectorXd start = hand_at(-0.4, 0.0, 0.3);
  Trajectory goals(2, 6);
  goals.row(0) = hand_at(0.0, 0.5, 0.3).transpose();  // inside the wall: dropped
  goals.row(1) = hand_at(0.4, 0.0, 0.3).transpose();
  const RrtResult res = planner.rrt_connect(start, goals);
  ASSERT_EQ(res.status, RrtStatus::solved);
  EXPECT_EQ(res.goal, 1);
  Trajectory bad(1, 6);
  bad.row(0) = goals.row(0);
  EXPECT_EQ(planner.rrt_connect(start, bad).status, RrtStatus::invalid_goals);
  EXPECT_EQ(planner.rrt_connect(bad.row(0).transpose(), goals).status, RrtStatus::invalid_start);
  EXPECT_THROW(planner.rrt_connect(hand_at(5, 0, 0), goals), std::invalid_argument);  // outside the limits
  EXPECT_THROW(planner.rrt_connect(start, Trajectory(0, 6)), std::invalid_argument);
}

TEST(MotionCheck, ThinBoardBetweenWaypointsIsCaught) {
  auto r = floating_hand();
  // A 1 mm board across the path: both waypoints are free, the segment is not.
  CollisionChecker c = hand_checker(*r, {solid("board", {0.001, 2.0, 2.0}, {0, 0, 0})});
  RrtSettings s;
  s.resolution = 0.0005;
  MotionPlanner planner(c, s);
  Trajectory path(2, 6);
  path.row(0) = hand_at(-0.3, 0, 0.2).transpose();
  path.row(1) = hand_at(0.3, 0, 0.2).transpose();
  EXPECT_EQ(planner.first_invalid_segment(path), 0);
  path.row(1) = hand_at(-0.1, 0, 0.2).transpose();  // stops short of it
  EXPECT_EQ(planner.first_invalid_segment(path), -1);
}

TEST(MotionCheck, CertifiedCheckCatchesAGrazeSamplingMisses) {
  auto r = floating_hand();
  // A 1 mm board that the hand crosses; sampled every 30 cm (at x = -0.3, 0, 0.3) the check steps
  // over it, proved it cannot.
  CollisionChecker c = hand_checker(*r, {solid("board", {0.001, 2.0, 2.0}, {0.15, 0, 0})});
  Trajectory path(2, 6);
  path.row(0) = hand_at(-0.3, 0, 0.2).transpose();
  path.row(1) = hand_at(0.3, 0, 0.2).transpose();
  RrtSettings s;
  s.resolution = 0.3;
  s.certified = false;
  const int sampled = MotionPlanner(c, s).first_invalid_segment(path);
  s.certified = true;
  EXPECT_EQ(MotionPlanner(c, s).first_invalid_segment(path), 0);
  // Free motions are proved free, whatever the resolution; the sampled check missed the board.
  path.row(1) = hand_at(-0.1, 0, 0.2).transpose();
  EXPECT_EQ(MotionPlanner(c, s).first_invalid_segment(path), -1);
  EXPECT_EQ(sampled, -1);
}

TEST(MotionCheck, CertifiedProofsHoldForEveryPieceAndMeetAWallMidwayFast) {
  auto r = floating_hand();
  // Two boxes 2 cm apart leave a slot the hand slides along at a few millimetres' clearance.
  CollisionChecker c =
      hand_checker(*r, {solid("left", {1.0, 0.2, 1.0}, {0, 0.2, 0}), solid("board", {0.001, 2.0, 2.0}, {0.9, 0, 0})});
  MotionPlanner planner(c);
  CollisionWorkspace ws(c);
  const Eigen::VectorXd a = hand_at(-0.4, 0.0, 0.2), b = hand_at(0.4, 0.0, 0.25);
  long checks = 0;
  ASSERT_TRUE(planner.motion_certified(a.data(), b.data(), ws, &checks));
  EXPECT_GT(checks, 2);
  // Every sub-segment of a proved segment proves again (the proof keeps a clearance, it is not a tie).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int k = 0; k < 50; ++k) {
    double s = u(rng), t = u(rng);
    if (s > t) std::swap(s, t);
    const Eigen::VectorXd x = a + s * (b - a), y = a + t * (b - a);
    EXPECT_TRUE(planner.motion_certified(x.data(), y.data(), ws)) << s << " " << t;
  }
  // A board halfway is met by the first query's neighbours: far fewer queries than proving the free half.
  const Eigen::VectorXd far_a = hand_at(0.5, 0.0, 0.2), far_b = hand_at(1.3, 0.0, 0.2);
  long through = 0, free_half = 0;
  EXPECT_FALSE(planner.motion_certified(far_a.data(), far_b.data(), ws, &through));
  const Eigen::VectorXd near_board = hand_at(0.75, 0.0, 0.2);
  EXPECT_TRUE(planner.motion_certified(far_a.data(), near_board.data(), ws, &free_half));
  EXPECT_LT(through, free_half);
}

TEST(CollisionCheck, MinDistanceWithACapIsTheLeastOfTheCapAndTheDistance) {
  auto r = floating_hand();
  CollisionChecker c = hand_checker(*r, {solid("board", {0.01, 2.0, 2.0}, {0.3, 0, 0})});
  CollisionWorkspace ws(c);
  const Eigen::VectorXd q = hand_at(0.0, 0.0, 0.2);
  const double d = c.min_distance(q.data(), ws);
  ASSERT_GT(d, 0.05);
  EXPECT_DOUBLE_EQ(c.min_distance(q.data(), ws, d + 0.1), d);
  EXPECT_DOUBLE_EQ(c.min_distance(q.data(), ws, 0.5 * d), 0.5 * d);
}

TEST(Shortcut, MinGainSkipsNegligibleShortcutsOnly) {
  auto r = floating_hand();
  // A box between the ends: the bend's vertex cannot be dropped, its corner can be cut.
  CollisionChecker c = hand_checker(*r, {solid("box", {0.1, 0.1, 0.1}, {0, 0, 0.2})});
  MotionPlanner planner(c);
  Trajectory bent(3, 6), straight(2, 6);
  bent.row(0) = hand_at(-0.4, 0, 0.2).transpose();
  bent.row(1) = hand_at(0.0, 0.35, 0.2).transpose();
  bent.row(2) = hand_at(0.4, 0, 0.2).transpose();
  straight.row(0) = bent.row(0);
  straight.row(1) = bent.row(2);
  ASSERT_EQ(planner.first_invalid_segment(bent), -1);
  ASSERT_EQ(planner.first_invalid_segment(straight), 0);
  auto length = [](const Trajectory& p) {
    double l = 0;
    for (long i = 0; i + 1 < p.rows(); ++i) l += (p.row(i + 1) - p.row(i)).norm();
    return l;
  };
  // Cutting the corner gains at most |bend| - |straight| = 0.26 of 1.06: never half the path.
  EXPECT_NEAR(length(planner.shortcut(bent, 50, 1, 0.5)), length(bent), 1e-12);
  const Trajectory cut = planner.shortcut(bent, 50, 1, 0.01);
  EXPECT_LT(length(cut), length(bent) - 0.05);
  EXPECT_EQ(planner.first_invalid_segment(cut), -1);
}
