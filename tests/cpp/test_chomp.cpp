// CHOMP and CHOMP-Proj (OMG Sec. III-A..D) on the mixed-joint test arm against independent truth:
// the gradient against finite differences of the cost, the prior against its closed form, the
// goal-set step against a dense solve of the equality-constrained quadratic program of eq. 7-8,
// and the goal-cost estimate against the objective of the explicit straight tail.
#include <cmath>
#include <memory>
#include <random>

#include <gtest/gtest.h>
#include <Eigen/Dense>

#include "arm_fixtures.hpp"
#include "mesh_fixtures.hpp"
#include "pickplan/omg/chomp.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

struct ChompCase {
  std::shared_ptr<const Robot> robot;
  std::shared_ptr<SceneSdf> scene;
  BodyPoints body;
  Eigen::VectorXd q0, q1;  // start and end of the test trajectory
};

// Random body points (seeded) within 0.1 m of the origins of the arm's moving links, and a
// 0.12 m box centred where link l4 is half-way along the straight path q0 -> q1, so the path
// runs through it: some points collide, some are in the padding, some are far.
ChompCase make_case() {
  ChompCase c;
  c.robot = std::make_shared<Robot>(Robot::from_urdf_file(kData + "/mixed_arm.urdf"));
  const Robot& r = *c.robot;
  c.q0.resize(r.dof());
  c.q1.resize(r.dof());
  c.q0 << -0.6, -0.1, 0.3, -0.2, 0.1;
  c.q1 << 0.7, 0.15, -0.4, 0.3, -0.2;
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  const int per_link = 12;
  c.body.points.resize(0, 3);
  for (const char* name : {"l1", "l2", "l3", "l4", "l5", "side"}) {
    const int l = r.link_index(name);
    for (int k = 0; k < per_link; ++k) {
      c.body.link.push_back(l);
      c.body.points.conservativeResize(c.body.points.rows() + 1, 3);
      c.body.points.bottomRows(1) << u(rng), u(rng), u(rng);
    }
  }
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d::Constant(0.12), V, F);
  auto grid = std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.15}));
  RobotWorkspace ws(r);
  const Eigen::VectorXd mid = 0.5 * (c.q0 + c.q1);
  r.forward_kinematics(mid.data(), ws);
  Transform pose;
  pose.p = ws.link_pose[r.link_index("l4")].p;
  c.scene = std::make_shared<SceneSdf>();
  c.scene->add_object(grid, pose);
  return c;
}

ChompSettings exact_settings() {  // every term, no clipping: the gradient is the cost's derivative
  ChompSettings s;
  s.n = 10;
  s.duration = 1.0;
  s.epsilon = 0.1;
  s.top_k = 0;
  s.clip_gradient = 0;
  return s;
}

ChompSettings planner_settings() {  // the top-k terms and the clipped gradient, as the planner runs
  ChompSettings s = exact_settings();
  s.top_k = 500;
  s.clip_gradient = 10.0;
  return s;
}

// The straight path q0 -> q1 over n waypoints plus a seeded wiggle on the inner ones.
Trajectory wiggly_path(const ChompCase& c, int n, double amplitude) {
  Trajectory xi(n, c.robot->dof());
  for (int t = 0; t < n; ++t) {
    const double s = double(t + 1) / n;
    xi.row(t) = ((1 - s) * c.q0 + s * c.q1).transpose();
    if (t < n - 1)
      for (int j = 0; j < xi.cols(); ++j) xi(t, j) += amplitude * std::sin(1.7 * t + 2.3 * j);
  }
  return xi;
}

}  // namespace

TEST(Chomp, ObjectiveGradientMatchesFiniteDifferences) {
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, exact_settings());
  ChompWorkspace ws(p);
  const Trajectory xi = wiggly_path(c, 10, 0.05);
  Trajectory grad;
  const ObjectiveTerms t = p.objective(xi, c.q0, 3, &grad, ws);
  ASSERT_GT(t.obstacle, 0.0);
  ASSERT_GT(t.colliding_points, 0);
  const double h = 1e-6;
  double worst = 0, scale = grad.cwiseAbs().maxCoeff();
  for (int r = 0; r < xi.rows(); ++r)
    for (int j = 0; j < xi.cols(); ++j) {
      Trajectory xp = xi, xm = xi;
      xp(r, j) += h;
      xm(r, j) -= h;
      const double fd =
          (p.objective(xp, c.q0, 3, nullptr, ws).total - p.objective(xm, c.q0, 3, nullptr, ws).total) / (2 * h);
      worst = std::max(worst, std::abs(fd - grad(r, j)));
    }
  EXPECT_LT(worst, 1e-4 * (1 + scale)) << "largest gradient entry " << scale;
}

TEST(Chomp, PriorIsHalfTheSquaredVelocityAndItsHessianIsA) {
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, exact_settings());
  const int n = 10;
  const double dt = 0.1;
  ASSERT_DOUBLE_EQ(p.dt(), dt);
  // Straight line: n equal steps of (q1 - q0) / n.
  Trajectory line(n, c.robot->dof());
  for (int t = 0; t < n; ++t) line.row(t) = (c.q0 + (c.q1 - c.q0) * double(t + 1) / n).transpose();
  EXPECT_NEAR(p.prior(line, c.q0, nullptr), (c.q1 - c.q0).squaredNorm() / (2 * n * dt * dt), 1e-10);
  // A is K^T K for first differences over dt: tridiagonal (2, -1) / dt^2 with a last diagonal of 1 / dt^2.
  const Eigen::MatrixXd A = p.A_matrix();
  for (int i = 0; i < n; ++i)
    for (int k = 0; k < n; ++k) {
      const double expected = i == k ? (i == n - 1 ? 1.0 : 2.0) : (std::abs(i - k) == 1 ? -1.0 : 0.0);
      EXPECT_NEAR(A(i, k), expected / (dt * dt), 1e-9);
    }
  // The prior is quadratic, so its gradient moves by A xi between any two trajectories.
  const Trajectory xi = wiggly_path(c, n, 0.2);
  Trajectory g1, g0;
  p.prior(xi, c.q0, &g1);
  p.prior(Trajectory::Zero(n, c.robot->dof()), c.q0, &g0);
  EXPECT_LT(((g1 - g0) - A * xi).cwiseAbs().maxCoeff(), 1e-8);
  // solve_A inverts A (the banded Cholesky against a dense solve).
  Trajectory out;
  p.solve_A(xi, out);
  EXPECT_LT((out - Trajectory(A.ldlt().solve(Eigen::MatrixXd(xi)))).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Chomp, StepDecreasesTheCost) {
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, planner_settings());
  ChompWorkspace ws(p);
  Trajectory xi = wiggly_path(c, 10, 0.05);
  const Eigen::RowVectorXd end = xi.bottomRows(1);
  for (int it = 0; it < 5; ++it) {
    const double before = p.objective(xi, c.q0, it, nullptr, ws).total;
    const StepInfo info = p.step(xi, c.q0, nullptr, it, ws);  // plain CHOMP: the end stays
    EXPECT_NEAR(info.before.total, before, 1e-12 * (1 + before));
    EXPECT_LT(p.objective(xi, c.q0, it, nullptr, ws).total, before) << "iteration " << it;
    EXPECT_EQ(xi.bottomRows(1), end);
  }
}

TEST(Chomp, GoalSetStepSolvesTheConstrainedQuadraticProgram) {
  // Eq. 7-8: the step minimises 1/2 D^T A D + s g^T D with the last m rows of xi + D on the goal.
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, exact_settings());
  ChompWorkspace ws(p);
  const int n = 10, d = c.robot->dof(), iteration = 2;
  const double s = p.settings().step_size;
  for (int m : {1, 3}) {
    const Trajectory xi = wiggly_path(c, n, 0.05);
    Trajectory goal(m, d);
    for (int k = 0; k < m; ++k) goal.row(k) = (c.q1 + Eigen::VectorXd::Constant(d, 0.02 * (k + 1))).transpose();
    Trajectory g;
    p.objective(xi, c.q0, iteration, &g, ws);
    // KKT system [A C^T; C 0] [D; mu] = [-s g; goal - C xi], C selecting the last m rows.
    Eigen::MatrixXd K = Eigen::MatrixXd::Zero(n + m, n + m);
    K.topLeftCorner(n, n) = p.A_matrix();
    for (int k = 0; k < m; ++k) K(n - m + k, n + k) = K(n + k, n - m + k) = 1.0;
    Eigen::MatrixXd rhs(n + m, d);
    rhs.topRows(n) = -s * g;
    rhs.bottomRows(m) = goal - xi.bottomRows(m);
    const Eigen::MatrixXd D = K.fullPivLu().solve(rhs).topRows(n);
    Trajectory stepped = xi;
    const StepInfo info = p.step(stepped, c.q0, &goal, iteration, ws);
    ASSERT_EQ(info.limit_projections, 0);
    EXPECT_LT((stepped - (xi + D)).cwiseAbs().maxCoeff(), 1e-9) << "m = " << m;
    EXPECT_LT((stepped.bottomRows(m) - goal).cwiseAbs().maxCoeff(), 1e-12);  // on the goal
    EXPECT_LT(info.goal_error, 1e-12);
  }
}

TEST(Chomp, OptimizeClearsTheObstacleAndStaysOnTheGoal) {
  // A fixed objective (no lambda growth, a light prior: the box is large for this small arm).
  ChompCase c = make_case();
  ChompSettings s = planner_settings();
  s.lambda = 0.01;
  s.lambda_growth = 1.0;
  ChompProblem p(c.robot, c.scene, c.body, s);
  const Trajectory xi = wiggly_path(c, 10, 0.05);
  Trajectory goal(1, c.robot->dof());
  goal.row(0) = c.q1.transpose();
  ChompWorkspace ws(p);
  const ObjectiveTerms start = p.objective(xi, c.q0, 0, nullptr, ws);
  ASSERT_GT(start.colliding_points, 0);
  const ChompResult r = p.optimize(xi, c.q0, goal, 120);
  EXPECT_EQ(r.iterations, 120);
  ASSERT_EQ(r.objective.size(), 120u);
  EXPECT_NEAR(r.objective.front(), start.total, 1e-12 * start.total);
  EXPECT_EQ(r.final_terms.colliding_points, 0);
  EXPECT_LT(r.final_terms.obstacle, 0.1 * start.obstacle);
  EXPECT_LT(r.final_terms.total, 0.5 * start.total);
  EXPECT_LT((r.xi.bottomRows(1) - goal).cwiseAbs().maxCoeff(), 1e-12);
  for (int t = 0; t < r.xi.rows(); ++t)
    for (int j = 0; j < r.xi.cols(); ++j) {
      EXPECT_GE(r.xi(t, j), c.robot->lower_limits()[j] - 1e-9);
      EXPECT_LE(r.xi(t, j), c.robot->upper_limits()[j] + 1e-9);
    }
}

TEST(Chomp, AStepEndsInsideTheJointLimitsWhenItsSmoothProjectionsRunOut) {
  // Every waypoint's joints pushed past both limits: one smooth projection (it fixes the worst joint) cannot
  // bring all back, the clamp after it must; the pinned tail stays on the goal.
  ChompCase c = make_case();
  ChompSettings s = exact_settings();
  s.joint_limit_steps = 1;
  ChompProblem p(c.robot, c.scene, c.body, s);
  ChompWorkspace ws(p);
  const Eigen::VectorXd& lo = c.robot->lower_limits();
  const Eigen::VectorXd& hi = c.robot->upper_limits();
  Trajectory xi = wiggly_path(c, 10, 0.05);
  for (int t = 0; t + 1 < xi.rows(); ++t)
    for (int j = 0; j < xi.cols(); ++j)
      if (std::isfinite(lo[j]) && std::isfinite(hi[j]))  // a continuous joint has no limit to leave
        xi(t, j) = (t + j) % 2 ? hi[j] + 0.01 * (t + 1) : lo[j] - 0.02 * (j + 1);
  Trajectory goal(1, c.robot->dof());
  goal.row(0) = c.q1.transpose();
  ASSERT_TRUE((lo.array().isFinite() && hi.array().isFinite()).any());
  const StepInfo info = p.step(xi, c.q0, &goal, 0, ws);
  EXPECT_EQ(info.limit_projections, 1);
  for (int t = 0; t < xi.rows(); ++t)
    for (int j = 0; j < xi.cols(); ++j) {
      EXPECT_GE(xi(t, j), lo[j]) << t << ", " << j;
      EXPECT_LE(xi(t, j), hi[j]) << t << ", " << j;
    }
  EXPECT_LT((xi.bottomRows(1) - goal).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(Chomp, GoalCostIsTheObjectiveOfTheStraightTail) {
  // At iteration 0 the estimate of OMG Sec. III-D is f of the constant-velocity path q0 -> goal.
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, exact_settings());
  ChompWorkspace ws(p);
  const int n = 10, d = c.robot->dof();
  Trajectory goals(2, d);
  goals.row(0) = c.q1.transpose();
  goals.row(1) = (c.q1 + Eigen::VectorXd::Constant(d, 0.1)).transpose();
  double out[2];
  p.goal_costs(wiggly_path(c, n, 0.05), c.q0, 0, 20, goals, 1, 1, out, ws);
  for (int g = 0; g < 2; ++g) {
    Trajectory line(n, d);
    for (int t = 0; t < n; ++t)
      line.row(t) = (c.q0 + (goals.row(g).transpose() - c.q0) * double(t + 1) / n).transpose();
    const ObjectiveTerms f = p.objective(line, c.q0, 0, nullptr, ws);
    ASSERT_GT(f.obstacle, 0.0);
    EXPECT_NEAR(out[g], f.total, 1e-9 * (1 + f.total)) << "goal " << g;
  }
}

TEST(Chomp, StridedGoalCostsEqualABruteForceSumOverEveryStridedPoint) {
  // The estimates with time and point strides at a later iteration (the tail starts at xi(k - 1)),
  // with and without a merged grid and link culling, against the formula summed over every strided
  // point at every strided step, each point's speed from its own previous strided position: culled
  // links and reused point buffers change nothing.
  ChompCase c = make_case();
  const Robot& r = *c.robot;
  const int n = 30, d = r.dof(), iteration = 7, horizon = 20;
  const Trajectory xi = wiggly_path(c, n, 0.05);
  // Goals around q1 and far from it: links come within reach of the box and leave it along a tail.
  const int G = 100;
  Trajectory goals(G, d);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  goals.row(0) = c.q1.transpose();
  for (int g = 1; g < G; ++g)
    for (int j = 0; j < d; ++j) goals(g, j) = c.q1[j] + u(rng) * (g < 4 ? 0.1 : 1.0);
  int total_reentries = 0;  // a culled link back within reach with a point inside the padding
  for (const bool merged : {false, true}) {
    auto scene = std::make_shared<SceneSdf>(*c.scene);
    if (merged) scene->merge(0);
    for (const bool culling : {false, true})
      for (const auto& [ts, ps] : {std::pair<int, int>{1, 1}, {2, 2}, {3, 2}, {2, 5}, {4, 1}}) {
        ChompSettings s = exact_settings();
        s.link_culling = culling;
        s.obstacle_tail = 1;
        s.n = n;
        s.epsilon = 0.03;  // small padding: links leave and re-enter reach, so culling skips some steps
        ChompProblem p(c.robot, scene, c.body, s);
        ChompWorkspace ws(p);
        double out[G];
        p.goal_costs(xi, c.q0, iteration, horizon, goals, ts, ps, out, ws);
        const int k = std::min(n - 1, n * iteration / horizon), L = n - k, last_t = L - s.obstacle_tail;
        const Eigen::VectorXd a = k == 0 ? c.q0 : Eigen::VectorXd(xi.row(k - 1).transpose());
        const double lambda = s.lambda * std::pow(s.lambda_growth, iteration), inv_dt = n / s.duration;
        double total_obstacle = 0;
        int reentries = 0;
        for (int g = 0; g < G; ++g) {
          const Eigen::VectorXd delta = goals.row(g).transpose() - a;
          double obstacle = 0;
          RobotWorkspace prev(r), cur(r);
          r.forward_kinematics(a.data(), prev);
          for (int t = ts; t <= last_t; t += ts) {
            const Eigen::VectorXd q = a + delta * (double(t) / L);
            r.forward_kinematics(q.data(), cur);
            for (const LinkGroup& grp : p.groups()) {
              const bool was = p.group_reach(prev, grp).any(), now = p.group_reach(cur, grp).any();
              if (culling && !was && now) {
                for (int u = grp.begin; u < grp.end; ++u)
                  if (scene->distance(cur.link_pose[grp.link].apply(c.body.points.row(u).transpose()), nullptr,
                                      s.epsilon) < s.epsilon)
                    ++reentries;
              }
            }
            for (int u = 0; u < c.body.size(); u += ps) {
              const Eigen::Vector3d x = cur.link_pose[c.body.link[u]].apply(c.body.points.row(u).transpose());
              const Eigen::Vector3d xp = prev.link_pose[c.body.link[u]].apply(c.body.points.row(u).transpose());
              obstacle +=
                  chomp_cost(scene->distance(x, nullptr, s.epsilon), s.epsilon, nullptr) * (x - xp).norm() * inv_dt;
            }
            prev = cur;
          }
          total_obstacle += obstacle;
          const double expected = lambda * 0.5 * delta.squaredNorm() / L * inv_dt * inv_dt + obstacle * ps;
          EXPECT_NEAR(out[g], expected, 1e-12 * (1 + expected))
              << "goal " << g << " merged " << merged << " culling " << culling << " strides " << ts << "," << ps;
        }
        EXPECT_GT(total_obstacle, 0.0);  // the tails pass the box: the obstacle term is exercised
        if (culling) total_reentries += reentries;
      }
  }
  EXPECT_GT(total_reentries, 0);  // so reusing a step's points for the next step's speed is exercised
}

TEST(Chomp, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  ChompCase c = make_case();
  ChompProblem p(c.robot, c.scene, c.body, exact_settings());
  ChompWorkspace ws(p);
  const Trajectory xi = wiggly_path(c, 10, 0.0);
  const Eigen::VectorXd q_short = c.q0.head(4);
  Trajectory g;
  expect_invalid_argument([&] { p.prior(xi.topRows(9), c.q0, &g); }, "trajectory rows: expected 10 waypoints, got 9");
  expect_invalid_argument([&] { p.prior(xi, q_short, &g); }, "start configuration: expected 5 joint values, got 4");
  expect_invalid_argument([&] { p.obstacle(xi.leftCols(4), c.q0, nullptr, ws); },
                          "trajectory columns: expected 5 joint values, got 4");
  expect_invalid_argument([&] { p.objective(xi, q_short, 0, &g, ws); }, "expected 5 joint values, got 4");
  Trajectory wrong_grad = Trajectory::Zero(10, 4);
  expect_invalid_argument([&] { p.obstacle(xi, c.q0, &wrong_grad, ws); }, "obstacle gradient columns: expected 5");
  Trajectory out;
  expect_invalid_argument([&] { p.solve_A(xi.topRows(9), out); }, "expected 10 rows, got 9");
  Trajectory x = xi;
  const Trajectory goal4 = Trajectory::Zero(1, 4), goal_long = Trajectory::Zero(11, 5);
  expect_invalid_argument([&] { p.step(x, c.q0, &goal4, 0, ws); },
                          "CHOMP goal: expected 5 joint values per row, got 4");
  expect_invalid_argument([&] { p.step(x, c.q0, &goal_long, 0, ws); }, "expected 1 to 10 goal rows, got 11");
  expect_invalid_argument([&] { p.step(x, q_short, nullptr, 0, ws); }, "expected 5 joint values, got 4");
  double costs[1];
  expect_invalid_argument([&] { p.goal_costs(xi, c.q0, 0, 10, goal4, 1, 1, costs, ws); },
                          "goals: expected 5 joint values per row, got 4");
  expect_invalid_argument([&] { p.optimize(xi, c.q0, xi.bottomRows(1), -1); }, "iterations must be >= 0, got -1");
  Trajectory nan_xi = xi;
  nan_xi(2, 1) = NAN;
  expect_invalid_argument([&] { p.step(nan_xi, c.q0, nullptr, 0, ws); }, "NaN or infinite");
  BodyPoints bad = c.body;
  bad.link.pop_back();
  expect_invalid_argument([&] { ChompProblem(c.robot, c.scene, bad, exact_settings()); },
                          "body points: links: expected");
  bad = c.body;
  bad.link[0] = 99;
  expect_invalid_argument([&] { ChompProblem(c.robot, c.scene, bad, exact_settings()); }, "link index 99 out of range");
  ChompSettings mask = exact_settings();
  mask.active = {true, false};
  expect_invalid_argument([&] { ChompProblem(c.robot, c.scene, c.body, mask); },
                          "active joint mask: expected 5 entries, got 2");
}
