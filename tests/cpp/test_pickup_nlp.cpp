// Pick-up on the move NLP: kinematics against the UR5 DH closed form, constraint derivatives
// against finite differences, Ipopt's derivative checker, stage feasibility, size checks.
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "pickplan/core/robot.hpp"
#include "pickplan/pickup/cases.hpp"
#include "pickplan/pickup/nlp.hpp"
#include "pickplan/pickup/poly_traj.hpp"
#include "pickup_fixtures.hpp"

using namespace pickplan::core;
using namespace pickplan::pickup;
namespace test = pickplan::test;

namespace {

Eigen::Matrix4d dh(double theta, double d, double a, double alpha) {
  Eigen::Matrix4d T;
  const double ct = std::cos(theta), st = std::sin(theta), ca = std::cos(alpha), sa = std::sin(alpha);
  T << ct, -st * ca, st * sa, a * ct, st, ct * ca, -ct * sa, a * st, 0, sa, ca, d, 0, 0, 0, 1;
  return T;
}

// World pose of the UR5 flange by the published DH table, on the planar base.
Eigen::Matrix4d flange_dh(const Eigen::VectorXd& q) {
  const double d[6] = {0.089159, 0, 0, 0.10915, 0.09465, 0.0823};
  const double a[6] = {0, -0.425, -0.39225, 0, 0, 0};
  const double al[6] = {M_PI / 2, 0, 0, M_PI / 2, -M_PI / 2, 0};
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.block<3, 3>(0, 0) = Eigen::AngleAxisd(q[2], Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T(0, 3) = q[0];
  T(1, 3) = q[1];
  Eigen::Matrix4d mount = Eigen::Matrix4d::Identity();
  mount(0, 3) = 0.1;
  mount(2, 3) = 0.35;
  T = T * mount;
  for (int i = 0; i < 6; ++i) T = T * dh(q[3 + i], d[i], a[i], al[i]);
  return T;
}

Robot load() { return test::load_mobile_ur5(); }
PickupSettings fast_settings() { return test::fast_pickup_settings(); }

}  // namespace

TEST(MobileUR5, ZeroPoseMatchesKnownUR5Values) {
  Robot r = load();
  ASSERT_EQ(r.dof(), 9);
  EXPECT_EQ(r.joint_names()[0], "base_x");
  EXPECT_EQ(r.joint_names()[3], "shoulder_pan_joint");
  RobotWorkspace ws(r);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(9);
  r.forward_kinematics(q.data(), ws);
  // The UR5 flange at zero joint angles is at (a2 + a3, -(d4 + d6), d1 - d5) in its base frame.
  const Eigen::Vector3d p = ws.link_pose[r.link_index("flange")].p - Eigen::Vector3d(0.1, 0, 0.35);
  EXPECT_NEAR(p.x(), -0.81725, 1e-12);
  EXPECT_NEAR(p.y(), -0.19145, 1e-12);
  EXPECT_NEAR(p.z(), -0.005491, 1e-12);
}

TEST(MobileUR5, ForwardKinematicsMatchesDHTable) {
  Robot r = load();
  RobotWorkspace ws(r);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-M_PI, M_PI);
  for (int trial = 0; trial < 100; ++trial) {
    Eigen::VectorXd q(9);
    for (int i = 0; i < 9; ++i) q[i] = u(rng);
    r.forward_kinematics(q.data(), ws);
    const Eigen::Matrix4d A = ws.link_pose[r.link_index("flange")].matrix(), B = flange_dh(q);
    EXPECT_LT((A - B).cwiseAbs().maxCoeff(), 1e-12);
    const Transform tool = ws.link_pose[r.link_index("tool")];
    const Eigen::Vector3d expect = B.block<3, 1>(0, 3) + 0.15 * B.block<3, 1>(0, 2);
    EXPECT_LT((tool.p - expect).norm(), 1e-12);
  }
}

TEST(PickupNlp, ConstraintJacobianMatchesFiniteDifferences) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 2, example_rho());
  PickupSettings st = fast_settings();
  PickupConstraints c(r, pb, st, 0);  // all constraints
  Eigen::VectorXd x = heuristic_seed(r, pb, st);
  std::mt19937 rng(5);
  std::normal_distribution<double> nz(0.0, 0.05);
  for (int k = 0; k < c.traj().num_coeffs(); ++k) x[k] += nz(rng);
  x[c.idx_Sg()] = 0.4;
  x[c.idx_Sc()] = 0.12;
  EXPECT_LT(test::jacobian_fd_error(c, x), 2e-5);
}

// A heading is an angle: the goal-yaw row has the same value when the base ends any whole number of
// turns further round (a path that loops round the part once ends a turn past the goal's number).
TEST(PickupNlp, GoalHeadingRowTakesTheNearestTurn) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  PickupConstraints c(r, pb, st, 1);
  const Eigen::VectorXd x = heuristic_seed(r, pb, st);
  const std::vector<std::string> names = c.row_names();
  int yaw = -1;
  for (int i = 0; i < static_cast<int>(names.size()); ++i)
    if (names[i].rfind("goal_yaw", 0) == 0) yaw = i;
  ASSERT_GE(yaw, 0);
  Eigen::VectorXd g0(c.num_constraints()), g1(c.num_constraints()), lo, hi, glo, ghi;
  c.bounds(lo, hi, glo, ghi);
  c.eval_g(x.data(), g0.data());
  ASSERT_GE(g0[yaw], glo[yaw]);  // the seed ends within the goal's tolerance
  ASSERT_LE(g0[yaw], ghi[yaw]);
  const int top = c.traj().offset(2) + c.traj().degree(2);  // the heading's s^d coefficient: moves phi(T) only
  Eigen::VectorXd q0(r.dof()), q1(r.dof());
  c.traj().eval(x.data(), 1.0, q0.data(), nullptr, nullptr);
  for (int turns : {1, -1, 3}) {
    Eigen::VectorXd xt = x;
    xt[top] += 2 * M_PI * turns;
    c.traj().eval(xt.data(), 1.0, q1.data(), nullptr, nullptr);
    ASSERT_NEAR(q1[2] - q0[2], 2 * M_PI * turns, 1e-9);
    c.eval_g(xt.data(), g1.data());
    EXPECT_NEAR(g1[yaw], g0[yaw], 1e-9) << turns << " turns";
    EXPECT_LT(test::jacobian_fd_error(c, xt), 2e-5);
  }
}

// The Hessian of the Lagrangian against central differences of the exact Jacobian, J(x)^T lambda,
// with random multipliers on every row (all stages' rows, a perturbed seed).
TEST(PickupNlp, LagrangianHessianMatchesFiniteDifferences) {
  Robot r = load();
  for (int case_id : {2, 4}) {
    PickupProblem pb = paper_case(r, case_id, example_rho());
    PickupSettings st = fast_settings();
    PickupConstraints c(r, pb, st, 0);
    Eigen::VectorXd x = heuristic_seed(r, pb, st);
    std::mt19937 rng(7 + case_id);
    std::normal_distribution<double> nz(0.0, 0.05);
    for (int k = 0; k < c.traj().num_coeffs(); ++k) x[k] += nz(rng);
    x[c.idx_Sg()] = 0.4;
    x[c.idx_Sc()] = 0.12;
    Eigen::VectorXd lam(c.num_constraints());
    for (int i = 0; i < lam.size(); ++i) lam[i] = nz(rng) * 20.0;
    const Eigen::MatrixXd H = c.dense_hessian(x, lam);
    EXPECT_LT((H - H.transpose()).cwiseAbs().maxCoeff(), 1e-9);
    // Packed lower triangle agrees with the dense matrix.
    std::vector<double> vals(c.num_hess_nonzeros());
    std::vector<int> hr(vals.size()), hc(vals.size());
    c.eval_hessian(x.data(), lam.data(), vals.data());
    c.hess_structure(hr.data(), hc.data());
    for (size_t e = 0; e < vals.size(); ++e) {
      ASSERT_GE(hr[e], hc[e]);
      EXPECT_DOUBLE_EQ(vals[e], H(hr[e], hc[e]));
    }
    const double worst = test::hessian_fd_error(c, x, lam, H);
    EXPECT_LT(worst, 1e-4) << "case " << case_id;
    std::printf("case %d: worst relative Hessian error %.2e\n", case_id, worst);
  }
}

TEST(PickupNlp, RhoGradientMatchesFiniteDifferences) {
  RhoPoly rho = example_rho();
  const double h = 1e-6;
  for (double sg : {0.1, 0.4, 1.0})
    for (double sc : {0.06, 0.1, 0.14}) {
      Eigen::Vector2d g = rho.gradient(sg, sc);
      EXPECT_NEAR(g[0], (rho.value(sg + h, sc) - rho.value(sg - h, sc)) / (2 * h), 1e-6);
      EXPECT_NEAR(g[1], (rho.value(sg, sc + h) - rho.value(sg, sc - h)) / (2 * h), 1e-6);
      EXPECT_LE(g[0], 1e-12);  // monotone surface
      EXPECT_GE(g[1], -1e-12);
    }
}

TEST(PickupNlp, IpoptDerivativeCheckerFindsNoErrors) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 4, example_rho());
  PickupSettings st = fast_settings();
  st.derivative_test = true;
  st.max_iter = 0;
  st.print_level = 0;
  st.output_file = ::testing::TempDir() + "pickup_dercheck.txt";
  Eigen::VectorXd x = heuristic_seed(r, pb, st);
  solve_stage(r, pb, st, 0, x);
  std::ifstream f(st.output_file);
  std::stringstream ss;
  ss << f.rdbuf();
  const std::string out = ss.str();
  ASSERT_NE(out.find("Starting derivative checker"), std::string::npos) << out.substr(0, 2000);
  EXPECT_NE(out.find("No errors detected by derivative checker"), std::string::npos) << out.substr(0, 4000);
}

TEST(PickupNlp, EachStageSatisfiesItsConstraints) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  PickupResult res = solve_successive(r, pb, st);
  ASSERT_TRUE(res.success) << res.status;
  ASSERT_EQ(res.stages.size(), 5u);
  for (const StageResult& s : res.stages) {
    PickupConstraints c(r, pb, st, s.stage);
    EXPECT_LT(c.max_violation(s.x), 1e-5) << "stage " << s.stage;
    EXPECT_TRUE(s.success) << "stage " << s.stage << ": " << s.ipopt_status;
  }
  EXPECT_GE(pb.rho.value(res.S_g, res.S_c), pb.gamma - 1e-6);
  EXPECT_NEAR((res.T2 - res.T1) * res.S_c, pb.stroke, 1e-6);
  EXPECT_LE(res.T2, res.T + 1e-9);
  // Pose at T2 by an independent FK evaluation of the final polynomials.
  Eigen::VectorXd q(9);
  res.traj.eval(res.x.data(), res.T2, q.data(), nullptr, nullptr);
  RobotWorkspace ws(r);
  r.forward_kinematics(q.data(), ws);
  EXPECT_LT((ws.link_pose[pb.tool_link].p - pb.grasp_pose.p).norm(), 1e-5);
}

TEST(PickupNlp, UnreachablePartReturnsStatusNotException) {
  Robot r = load();
  PaperCaseOptions opt;
  opt.part_z = 3.5;  // far above anything the UR5 on its base can reach
  opt.obstacles = false;
  PickupProblem pb = paper_case(r, 1, example_rho(), opt);
  PickupSettings st = fast_settings();
  st.max_iter = 200;
  PickupResult res;
  ASSERT_NO_THROW(res = solve_successive(r, pb, st));
  EXPECT_FALSE(res.success);
  EXPECT_EQ(res.stages_completed, 1);  // the base-only stage is feasible; the grasp pose is not
  EXPECT_EQ(res.status, SolveStatus::infeasible) << res.stages.back().ipopt_status;
  EXPECT_EQ(res.x.size(), res.stages[0].x.size());
}

TEST(PickupNlp, TimeLimitStopsTheSolveWithItsStatus) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  st.time_limit = 1e-6;  // spent before the first Ipopt iteration ends
  PickupResult res = solve_successive(r, pb, st);
  EXPECT_EQ(res.status, SolveStatus::time_limit) << res.stages.back().ipopt_status;
  EXPECT_FALSE(res.success);
  EXPECT_EQ(solve_stage(r, pb, st, 1, heuristic_seed(r, pb, st)).status, SolveStatus::time_limit);
  // A limit that is never reached changes nothing: the same solution, bit for bit.
  PickupSettings loose = fast_settings();
  loose.time_limit = 1e5;
  const PickupResult a = solve_successive(r, pb, fast_settings()), b = solve_successive(r, pb, loose);
  ASSERT_TRUE(a.success);
  EXPECT_EQ(b.status, SolveStatus::solved);
  EXPECT_EQ(a.x, b.x);
}

TEST(PickupNlp, BadInputThrowsClearErrors) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  Eigen::VectorXd x = heuristic_seed(r, pb, st);
  PickupConstraints c(r, pb, st, 1);
  x[c.idx_s1()] = 0.6;
  x[c.idx_s2()] = 0.4;
  EXPECT_THROW(solve_stage(r, pb, st, 1, x), std::invalid_argument);
  EXPECT_THROW(solve_stage(r, pb, st, 7, heuristic_seed(r, pb, st)), std::invalid_argument);
  pb.arm_start.resize(5);
  EXPECT_THROW(heuristic_seed(r, pb, st), std::invalid_argument);
}

TEST(PickupNlp, SizeChecksNameTheProblem) {
  using test::expect_invalid_argument;
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  const Eigen::VectorXd x = heuristic_seed(r, pb, st);
  const PickupConstraints c(r, pb, st, 5);
  const std::string n = std::to_string(c.num_vars()), m = std::to_string(c.num_constraints());
  const Eigen::VectorXd short_x = x.head(x.size() - 1);
  const std::string got = "expected " + n + " values, got " + std::to_string(x.size() - 1);
  expect_invalid_argument([&] { c.dense_jacobian(short_x); }, got);
  expect_invalid_argument([&] { c.max_violation(short_x); }, got);
  expect_invalid_argument([&] { c.near_rows(short_x, 0.1, 0.1); }, got);
  expect_invalid_argument([&] { c.dense_points(short_x, 4, 0.01, 0.01); }, got);
  expect_invalid_argument([&] { c.dense_hessian(short_x, Eigen::VectorXd::Zero(c.num_constraints())); }, got);
  expect_invalid_argument([&] { c.dense_hessian(x, Eigen::VectorXd::Zero(3)); },
                          "lambda: expected " + m + " values (one per constraint row), got 3");
  expect_invalid_argument([&] { c.dense_points(x, 0, 0.01, 0.01); }, "subdivisions must be >= 1, got 0");
  expect_invalid_argument([&] { solve_stage(r, pb, st, 1, short_x); }, "seed: expected " + n + " variables");
  PickupResult res;
  res.x = x;
  res.traj = PolyTraj(std::vector<int>(8, 3), 1.0);  // 8 DOFs for a 9-DOF robot
  res.x.resize(res.traj.num_coeffs() + 5);
  res.x.setZero();
  expect_invalid_argument([&] { evaluate_pickup(r, pb, res); },
                          "result trajectory: expected 9 DOFs (the robot's), got 8");
  pb.arm_start.resize(5);
  expect_invalid_argument([&] { PickupConstraints(r, pb, st, 1); }, "arm_start: expected 6 joint values, got 5");
}
