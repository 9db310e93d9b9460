// Goal sets (grasps -> IK -> standoff approach -> collision and diversity filters) on a constructed
// scene: the floating hand and blocks placed so that each grasp has one known outcome; the kept
// goals and their approach tails are checked by forward kinematics.
#include <algorithm>
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/omg/goal_set.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

Transform hand_at(double x, double y, double z) {  // identity rotation: the approach is world +z
  Transform T;
  T.p = Eigen::Vector3d(x, y, z);
  return T;
}

Transform translation(const Eigen::Vector3d& p) {
  Transform T;
  T.p = p;
  return T;
}

struct GoalCase {
  std::shared_ptr<const Robot> robot = test::floating_hand();
  int hand = robot->link_index("hand");
  IkSolver ik{robot, hand};
  std::vector<LinkMesh> hand_mesh{{"hand", link_collision_mesh(*robot, hand)}};
  Eigen::VectorXd start = Eigen::VectorXd::Zero(6);
};

// The palm spans z - 0.07 .. z - 0.03 under a hand at height z; the standoff is 8 cm (default).
enum Grasp { kFree, kUnreachable, kInBlock, kPreGraspInShelf, kBelowTheLift, kSameAsFree, kTooFar, kGrasps };

std::vector<Transform> grasps() {
  std::vector<Transform> g(kGrasps);
  g[kFree] = hand_at(0.5, 0, 0.3);
  g[kUnreachable] = hand_at(3.0, 0, 0.3);      // x is limited to [-1, 1]
  g[kInBlock] = hand_at(-0.5, 0, 0.3);         // the palm crosses a 6 cm block at z 0.22 .. 0.28
  g[kPreGraspInShelf] = hand_at(0, 0.5, 0.3);  // 8 cm back, the palm (z 0.15 .. 0.19) enters a shelf at z 0.12 .. 0.16
  g[kBelowTheLift] = hand_at(0, -0.5, -0.49);  // the lift stops at z = -0.5: no room to back off 2 cm
  g[kSameAsFree] = g[kFree];
  g[kTooFar] = hand_at(0.8, 0, 0.3);  // rejected by the approach test below
  return g;
}

std::vector<SceneObject> blocks() {
  return {{"block", TriangleMesh::box(Eigen::Vector3d::Constant(0.06)), translation({-0.5, 0, 0.25})},
          {"shelf", TriangleMesh::box(Eigen::Vector3d(0.2, 0.2, 0.04)), translation({0, 0.5, 0.14})}};
}

bool within_reach(const Eigen::VectorXd& q) { return q[0] <= 0.7; }

}  // namespace

TEST(GoalSet, EachGraspGetsItsReason) {
  GoalCase c;
  const CollisionChecker checker(*c.robot, c.hand_mesh, blocks());
  const GoalSet set = build_goal_set(c.ik, &checker, nullptr, grasps(), c.start, {}, within_reach);
  ASSERT_EQ(set.reasons.size(), size_t(kGrasps));
  EXPECT_EQ(set.reasons[kUnreachable], GoalReason::unreachable);
  EXPECT_EQ(set.reasons[kInBlock], GoalReason::in_collision);
  EXPECT_EQ(set.reasons[kPreGraspInShelf], GoalReason::standoff_in_collision);
  EXPECT_EQ(set.reasons[kBelowTheLift], GoalReason::standoff_unreachable);
  EXPECT_EQ(set.reasons[kTooFar], GoalReason::approach_clearance);
  // The two identical grasps: whichever is tried first is kept, the other is its duplicate.
  std::vector<std::string> pair = {to_string(set.reasons[kFree]), to_string(set.reasons[kSameAsFree])};
  std::sort(pair.begin(), pair.end());
  EXPECT_EQ(pair, (std::vector<std::string>{"duplicate", "ok"}));
  ASSERT_EQ(set.goals.rows(), 1);
  ASSERT_EQ(set.tails.size(), 1u);
  const int kept = set.grasp_index[0];
  EXPECT_TRUE(kept == kFree || kept == kSameAsFree);
  // The goal puts the hand on the grasp; tail row k puts it (4 - k) * 2 cm back along the approach.
  const Trajectory& tail = set.tails[0];
  ASSERT_EQ(tail.rows(), 5);
  EXPECT_EQ(tail.row(4), set.goals.row(0));
  RobotWorkspace ws(*c.robot);
  for (int k = 0; k < 5; ++k) {
    const Eigen::VectorXd q = tail.row(k).transpose();
    c.robot->forward_kinematics(q.data(), ws);
    const Transform& H = ws.link_pose[c.hand];
    EXPECT_LT((H.p - Eigen::Vector3d(0.5, 0, 0.3 - 0.02 * (4 - k))).norm(), 1e-3) << "tail row " << k;
    EXPECT_LT((H.R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(), 1e-2);
    EXPECT_FALSE(checker.in_collision(q));
    if (k > 0) EXPECT_LE((tail.row(k) - tail.row(k - 1)).cwiseAbs().maxCoeff(), 0.5);
  }
}

TEST(GoalSet, HandCheckerRejectsEarlyWithTheSameReasons) {
  GoalCase c;
  const CollisionChecker checker(*c.robot, c.hand_mesh, blocks());
  const GoalSet full = build_goal_set(c.ik, &checker, nullptr, grasps(), c.start, {}, within_reach);
  const GoalSet early = build_goal_set(c.ik, &checker, &checker, grasps(), c.start, {}, within_reach);
  EXPECT_EQ(early.reasons, full.reasons);
  EXPECT_EQ(early.goals, full.goals);
  // Without any checker nothing collides: the block and the shelf grasps become goals.
  const GoalSet blind = build_goal_set(c.ik, nullptr, nullptr, grasps(), c.start);
  EXPECT_EQ(blind.reasons[kInBlock], GoalReason::ok);
  EXPECT_EQ(blind.reasons[kPreGraspInShelf], GoalReason::ok);
  EXPECT_EQ(blind.reasons[kTooFar], GoalReason::ok);
  EXPECT_EQ(blind.goals.rows(), 4);
}

TEST(GoalSet, CapKeepsASeededSubsetInInputOrder) {
  GoalCase c;
  std::vector<Transform> poses;
  for (int k = 0; k < 5; ++k) poses.push_back(hand_at(0.5, -0.3 + 0.15 * k, 0.3));
  GoalSetSettings s;
  s.max_goals = 2;
  for (unsigned seed : {0u, 1u, 2u}) {
    s.seed = seed;
    const GoalSet set = build_goal_set(c.ik, nullptr, nullptr, poses, c.start, s);
    EXPECT_EQ(std::count(set.reasons.begin(), set.reasons.end(), GoalReason::ok), 2) << "seed " << seed;
    EXPECT_EQ(std::count(set.reasons.begin(), set.reasons.end(), GoalReason::over_cap), 3) << "seed " << seed;
    ASSERT_EQ(set.grasp_index.size(), 2u);
    EXPECT_LT(set.grasp_index[0], set.grasp_index[1]);
    for (int g = 0; g < 2; ++g) EXPECT_NEAR(set.goals(g, 1), -0.3 + 0.15 * set.grasp_index[g], 1e-3);
    const GoalSet again = build_goal_set(c.ik, nullptr, nullptr, poses, c.start, s);
    EXPECT_EQ(again.reasons, set.reasons);  // seeded
  }
}

TEST(GoalSet, AWorldApproachBacksOffAlongItWhateverTheHandsAxis) {
  // A place comes down along gravity: the hand, tilted 0.6 rad about x, backs off straight up.
  GoalCase c;
  Transform tilted = hand_at(0.4, 0.1, 0.2);
  tilted.R = axis_angle(Eigen::Vector3d::UnitX(), 0.6);
  GoalSetSettings s;
  s.approach = Eigen::Vector3d(0, 0, -1);
  const GoalSet set = build_goal_set(c.ik, nullptr, nullptr, {tilted}, c.start, s);
  ASSERT_EQ(set.goals.rows(), 1);
  RobotWorkspace ws(*c.robot);
  for (int k = 0; k < 5; ++k) {
    const Eigen::VectorXd q = set.tails[0].row(k).transpose();
    c.robot->forward_kinematics(q.data(), ws);
    EXPECT_LT((ws.link_pose[c.hand].p - Eigen::Vector3d(0.4, 0.1, 0.2 + 0.02 * (4 - k))).norm(), 1e-3) << "row " << k;
    EXPECT_LT((ws.link_pose[c.hand].R - tilted.R).cwiseAbs().maxCoeff(), 1e-2);
  }
  s.approach = Eigen::Vector3d(0, 0, -2);  // not a unit vector
  EXPECT_THROW(build_goal_set(c.ik, nullptr, nullptr, {tilted}, c.start, s), std::invalid_argument);
}

TEST(GoalSet, TheApproachClearanceIsAskedBetweenTheTailsConfigurations) {
  // The default approach: the tail rises from z 0.22 (pre-grasp) to 0.30 in 2 cm steps, joint-linearly
  // between them as the success test interpolates. A band 0.245 < z < 0.255 holds no tail configuration,
  // only the midpoint between the second and third: the waypoints alone pass, substeps 2 catch it.
  GoalCase c;
  const auto clear_of_band = [](const Eigen::VectorXd& q) { return q[2] <= 0.245 || q[2] >= 0.255; };
  GoalSetSettings s;
  const GoalSet at_waypoints =
      build_goal_set(c.ik, nullptr, nullptr, {hand_at(0.5, 0, 0.3)}, c.start, s, clear_of_band);
  ASSERT_EQ(at_waypoints.reasons, std::vector<GoalReason>{GoalReason::ok});
  s.approach_substeps = 2;
  const GoalSet between = build_goal_set(c.ik, nullptr, nullptr, {hand_at(0.5, 0, 0.3)}, c.start, s, clear_of_band);
  EXPECT_EQ(between.reasons, std::vector<GoalReason>{GoalReason::approach_clearance});
  // what it asks: every tail configuration and the joint-linear quarter points between them
  s.approach_substeps = 4;
  std::vector<double> asked;
  const auto record = [&](const Eigen::VectorXd& q) {
    asked.push_back(q[2]);
    return true;
  };
  const GoalSet quarters = build_goal_set(c.ik, nullptr, nullptr, {hand_at(0.5, 0, 0.3)}, c.start, s, record);
  ASSERT_EQ(quarters.goals.rows(), 1);
  for (int k = 0; k <= 16; ++k) {
    const double z = 0.22 + 0.005 * k;
    EXPECT_TRUE(std::any_of(asked.begin(), asked.end(), [&](double a) { return std::abs(a - z) < 1e-4; })) << z;
  }
  s.approach_substeps = 0;
  EXPECT_THROW(build_goal_set(c.ik, nullptr, nullptr, {hand_at(0.5, 0, 0.3)}, c.start, s), std::invalid_argument);
}

TEST(GoalSet, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  GoalCase c;
  const Robot other = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  const CollisionChecker wrong(other, {{"l0", link_collision_mesh(other, other.link_index("l0"))}}, {});
  expect_invalid_argument([&] { build_goal_set(c.ik, &wrong, nullptr, grasps(), c.start); },
                          "collision checker robot: expected 6 joints, got 5");
  expect_invalid_argument([&] { build_goal_set(c.ik, nullptr, &wrong, grasps(), c.start); },
                          "hand checker robot: expected 6 joints, got 5");
  expect_invalid_argument([&] { build_goal_set(c.ik, nullptr, nullptr, grasps(), c.start.head(5)); },
                          "expected 6 joint values, got 5");
  GoalSetSettings s;
  s.max_goals = 0;
  expect_invalid_argument([&] { build_goal_set(c.ik, nullptr, nullptr, grasps(), c.start, s); }, "max_goals >= 1");
}
