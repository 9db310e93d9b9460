// STOMP refinement (Kalakrishnan et al.; Thakar et al. Sec. V-B) on a mobile two-link arm: the
// cost never increases, the held waypoints and the base stay, and joint position and rate limits
// hold. Smoothness, clearance and limits are recomputed here from the returned waypoints.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/pickup/cases.hpp"
#include "pickplan/pickup/stomp.hpp"
#include "pickup_fixtures.hpp"

using namespace pickplan::core;
using namespace pickplan::pickup;
namespace test = pickplan::test;

namespace {

constexpr double kRate = 2.0;  // rad/s, both arm joints

struct StompCase {
  std::shared_ptr<const Robot> robot = test::mobile_two_link();
  Eigen::VectorXd rates = Eigen::VectorXd::Constant(2, kRate);
  std::vector<BodySphere> spheres;
  StompCase() {
    const int upper = robot->link_index("upper"), fore = robot->link_index("fore");
    spheres = {{upper, Eigen::Vector3d(0.25, 0, 0), 0.05},
               {fore, Eigen::Vector3d(0.2, 0, 0), 0.05},
               {fore, Eigen::Vector3d(0.4, 0, 0), 0.04}};
  }
  // N waypoints: base still at the origin, the arm joints from a to b plus a fixed wiggle.
  Eigen::MatrixXd path(int N, Eigen::Vector2d a, Eigen::Vector2d b, double wiggle) const {
    Eigen::MatrixXd Q = Eigen::MatrixXd::Zero(N, 5);
    for (int i = 0; i < N; ++i) {
      const double s = double(i) / (N - 1);
      Q.block<1, 2>(i, 3) = ((1 - s) * a + s * b).transpose();
      if (i >= 2 && i < N - 2) Q(i, 3) += wiggle * std::sin(2.5 * i), Q(i, 4) += wiggle * std::cos(1.9 * i);
    }
    return Q;
  }
  double min_clearance(const Eigen::MatrixXd& Q, const std::vector<SphereObstacle>& obstacles) const {
    RobotWorkspace ws(*robot);
    double out = std::numeric_limits<double>::infinity();
    for (int i = 0; i < Q.rows(); ++i) {
      const Eigen::VectorXd q = Q.row(i).transpose();
      robot->forward_kinematics(q.data(), ws);
      for (const auto& b : spheres)
        for (const auto& o : obstacles)
          out = std::min(out, (ws.link_pose[b.link].apply(b.center) - o.center).norm() - b.radius - o.radius);
    }
    return out;
  }
};

// Sum of squared arm accelerations (second differences / dt^2) times dt over the inner waypoints.
double smoothness(const Eigen::MatrixXd& Q, double dt) {
  double s = 0;
  for (int i = 1; i + 1 < Q.rows(); ++i)
    s += (Q.row(i + 1).tail(2) - 2 * Q.row(i).tail(2) + Q.row(i - 1).tail(2)).squaredNorm() / std::pow(dt, 4);
  return s * dt;
}

// Positions inside the limits and central-difference rates within kRate at every waypoint.
void expect_within_limits(const Robot& robot, const Eigen::MatrixXd& Q, double dt) {
  for (int i = 0; i < Q.rows(); ++i)
    for (int j = 3; j < 5; ++j) {
      EXPECT_GE(Q(i, j), robot.lower_limits()[j] - 1e-12) << "waypoint " << i << " joint " << j;
      EXPECT_LE(Q(i, j), robot.upper_limits()[j] + 1e-12) << "waypoint " << i << " joint " << j;
      if (i > 0 && i + 1 < Q.rows()) EXPECT_LE(std::abs(Q(i + 1, j) - Q(i - 1, j)) / (2 * dt), kRate + 1e-9);
    }
}

void expect_ends_and_base_held(const Eigen::MatrixXd& Q0, const Eigen::MatrixXd& Q) {
  const int N = static_cast<int>(Q0.rows());
  for (int i : {0, 1, N - 2, N - 1}) EXPECT_EQ(Q.row(i), Q0.row(i)) << "waypoint " << i;
  EXPECT_EQ(Q.leftCols(3), Q0.leftCols(3));
}

}  // namespace

TEST(Stomp, SmoothsAWigglyPathWithoutRaisingTheCost) {
  StompCase c;
  const double dt = 0.1;
  const Eigen::MatrixXd Q0 = c.path(20, {0, 0}, {1, -0.5}, 0.05);
  const StompResult r = stomp_refine(*c.robot, Q0, dt, c.rates, c.spheres, {});
  EXPECT_EQ(r.iterations, 40);
  EXPECT_LE(r.final_cost, r.initial_cost);
  EXPECT_NEAR(r.initial_smoothness, smoothness(Q0, dt), 1e-9 * r.initial_smoothness);
  EXPECT_NEAR(r.final_smoothness, smoothness(r.q, dt), 1e-9 * r.initial_smoothness);
  EXPECT_LT(r.final_smoothness, 0.5 * r.initial_smoothness);
  EXPECT_TRUE(r.limits_ok);
  expect_within_limits(*c.robot, r.q, dt);
  expect_ends_and_base_held(Q0, r.q);
  const StompResult again = stomp_refine(*c.robot, Q0, dt, c.rates, c.spheres, {});
  EXPECT_EQ(again.q, r.q);  // seeded
}

TEST(Stomp, MovesWaypointsOutOfAnObstacle) {
  // The straight arm sweeps its tool (0.9 m from the shoulder) slowly through a sphere in its way:
  // 8 of the 20 waypoints collide. (With the default control weight the smoothness step pulls
  // back toward the straight path each iteration, so the deepest waypoints stay in; measured:
  // 8 -> 4 colliding, cost 508 -> 269.)
  StompCase c;
  const double dt = 0.1;
  const std::vector<SphereObstacle> obstacles = {{Eigen::Vector3d(0.9, 0, 0.3), 0.05}};
  const Eigen::MatrixXd Q0 = c.path(20, {-0.25, 0}, {0.25, 0}, 0.0);
  const StompResult r = stomp_refine(*c.robot, Q0, dt, c.rates, c.spheres, obstacles);
  auto colliding = [&](const Eigen::MatrixXd& Q) {
    int n = 0;
    for (int i = 0; i < Q.rows(); ++i) n += c.min_clearance(Q.row(i), obstacles) < 0;
    return n;
  };
  EXPECT_EQ(colliding(Q0), 8);
  EXPECT_LE(colliding(r.q), 4);
  EXPECT_LT(r.final_cost, 0.75 * r.initial_cost);
  EXPECT_NEAR(r.min_clearance, c.min_clearance(r.q, obstacles), 1e-12);
  EXPECT_TRUE(r.limits_ok);
  expect_within_limits(*c.robot, r.q, dt);
  expect_ends_and_base_held(Q0, r.q);
}

TEST(Stomp, ReturnsAnIterateInsideTheLimitsWhenTheStartIsOutside) {
  StompCase c;
  const int N = 30;
  const double dt = 0.2;
  Eigen::MatrixXd Q0 = c.path(N, {0, 0}, {0, 0}, 0.0);
  for (int i = 0; i < N; ++i) Q0(i, 3) = 2.1 * std::sin(M_PI * i / (N - 1));  // peaks 0.1 rad past the limit
  const StompResult r = stomp_refine(*c.robot, Q0, dt, c.rates, c.spheres, {});
  EXPECT_TRUE(r.limits_ok);
  expect_within_limits(*c.robot, r.q, dt);
  expect_ends_and_base_held(Q0, r.q);
}

// Moved from test_pickup_nlp.cpp: the mobile UR5 beside the pedestal of paper case 1.
TEST(Stomp, RefinesArmKeepsEndsAndLimits) {
  Robot r = test::load_mobile_ur5();
  PickupProblem pb = paper_case(r, 1, example_rho());
  const int N = 30;
  const double dt = 0.1;
  Eigen::MatrixXd Q(N, 9);
  std::mt19937 rng(2);
  std::normal_distribution<double> nz(0.0, 0.15);
  for (int i = 0; i < N; ++i) {
    const double s = double(i) / (N - 1);
    Q.row(i).head<3>() << 2.4 + 0.3 * s, 3.3, 0.0;  // base parked next to the pedestal
    Q.row(i).tail<6>() = pb.arm_start.transpose() * (1 - s) + Eigen::RowVectorXd::Constant(6, 0.3) * s;
    if (i >= 2 && i < N - 2) Q.row(i).tail<6>() += Eigen::RowVectorXd::NullaryExpr(6, [&]() { return nz(rng); });
  }
  StompSettings st;
  st.iterations = 30;
  StompResult res = stomp_refine(r, Q, dt, Eigen::VectorXd::Constant(6, M_PI), pb.body_spheres, pb.obstacles, st);
  EXPECT_EQ(res.iterations, 30);
  EXPECT_LT((res.q.topRows(2) - Q.topRows(2)).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((res.q.bottomRows(2) - Q.bottomRows(2)).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((res.q.leftCols(3) - Q.leftCols(3)).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LE(res.final_cost, res.initial_cost);
  EXPECT_LT(res.final_smoothness, 0.5 * res.initial_smoothness);  // the noisy path gets smoother
  EXPECT_GE(res.min_clearance, -1e-9);
  EXPECT_TRUE(res.limits_ok);
  EXPECT_LE(res.max_rate, M_PI + 1e-9);
  EXPECT_THROW(stomp_refine(r, Q.topRows(4), dt, Eigen::VectorXd::Constant(6, M_PI), pb.body_spheres, pb.obstacles, st),
               std::invalid_argument);
}

TEST(Stomp, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  StompCase c;
  const Eigen::MatrixXd Q0 = c.path(10, {0, 0}, {1, 1}, 0.0);
  const Robot& robot = *c.robot;
  expect_invalid_argument([&] { stomp_refine(robot, Q0.leftCols(4), 0.1, c.rates, c.spheres, {}); },
                          "stomp: waypoints: expected 5 joint values per row, got 4");
  expect_invalid_argument([&] { stomp_refine(robot, Q0.topRows(4), 0.1, c.rates, c.spheres, {}); },
                          "need at least 5 waypoints, got 4");
  expect_invalid_argument([&] { stomp_refine(robot, Q0, 0.1, Eigen::VectorXd::Ones(3), c.spheres, {}); },
                          "stomp: arm rate limits: expected 2 values, got 3");
  expect_invalid_argument([&] { stomp_refine(robot, Q0, 0.0, c.rates, c.spheres, {}); }, "dt must be positive");
  Eigen::MatrixXd nan = Q0;
  nan(4, 3) = NAN;
  expect_invalid_argument([&] { stomp_refine(robot, nan, 0.1, c.rates, c.spheres, {}); }, "stomp: waypoints: value");
  std::vector<BodySphere> bad = c.spheres;
  bad[1].link = 99;
  expect_invalid_argument([&] { stomp_refine(robot, Q0, 0.1, c.rates, bad, {}); }, "body sphere link out of range");
  StompSettings s;
  s.rollouts = 1;
  expect_invalid_argument([&] { stomp_refine(robot, Q0, 0.1, c.rates, c.spheres, {}, s); }, "rollouts >= 2");
}
