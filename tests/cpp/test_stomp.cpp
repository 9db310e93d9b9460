// STOMP refinement (Kalakrishnan et al.; Thakar et al. Sec. V-B) on a mobile two-link arm: the
// cost never increases, the held waypoints and the base stay, and joint position and rate limits
// hold. Smoothness, clearance and limits are recomputed here from the returned waypoints.
#include <cmath>
#include <limits>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/pickup/stomp.hpp"

using namespace pickplan;

namespace {

constexpr double kRate = 2.0;  // rad/s, both arm joints

struct StompCase {
  std::shared_ptr<const Robot> robot = test::mobile_two_link();
  Eigen::VectorXd rates = Eigen::VectorXd::Constant(2, kRate);
  std::vector<BodySphere> spheres;
  StompCase() {
    const int upper = robot->link_index("upper"), fore = robot->link_index("fore");
    spheres = {{upper, Eigen::Vector3d(0.25, 0, 0), 0.05}, {fore, Eigen::Vector3d(0.2, 0, 0), 0.05},
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

TEST(Stomp, BendsTheArmAwayFromAnObstacle) {
  // The straight arm sweeps its tool (0.9 m from the shoulder) through a sphere in its way.
  StompCase c;
  const double dt = 0.1;
  const std::vector<SphereObstacle> obstacles = {{Eigen::Vector3d(0.9, 0, 0.3), 0.05}};
  const Eigen::MatrixXd Q0 = c.path(20, {-0.8, 0}, {0.8, 0}, 0.0);
  const double before = c.min_clearance(Q0, obstacles);
  ASSERT_LT(before, -0.04);
  StompSettings s;
  s.iterations = 60;
  const StompResult r = stomp_refine(*c.robot, Q0, dt, c.rates, c.spheres, obstacles, s);
  EXPECT_LT(r.final_cost, r.initial_cost);
  const double after = c.min_clearance(r.q, obstacles);
  EXPECT_NEAR(r.min_clearance, after, 1e-12);
  EXPECT_GT(after, before + 0.05);
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
