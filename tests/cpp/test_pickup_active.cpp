// Pick-up NLP, active-set machinery: row subsets (incl. collision rows between samples) with exact
// derivatives, the dense collision check between samples, the S_g bound implied by rho >= gamma,
// and the final trajectories of the collision-prone cases checked densely.
#include <cmath>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "pickplan/core/robot.hpp"
#include "pickplan/pickup/cases.hpp"
#include "pickplan/pickup/nlp.hpp"
#include "pickup_fixtures.hpp"

using namespace pickplan::core;
using namespace pickplan::pickup;
namespace test = pickplan::test;

namespace {

Robot load() { return test::load_mobile_ur5(); }
PickupSettings fast_settings() { return test::fast_pickup_settings(); }

Eigen::VectorXd perturbed_seed(const Robot& r, const PickupProblem& pb, const PickupSettings& st,
                               const PickupConstraints& c, unsigned seed) {
  Eigen::VectorXd x = heuristic_seed(r, pb, st);
  std::mt19937 rng(seed);
  std::normal_distribution<double> nz(0.0, 0.05);
  for (int k = 0; k < c.traj().num_coeffs(); ++k) x[k] += nz(rng);
  x[c.idx_Sg()] = 0.3;
  x[c.idx_Sc()] = 0.12;
  return x;
}

// Clearance of body sphere / obstacle `pair` at normalised time s of x.
double pair_clearance(const Robot& r, const PickupProblem& pb, const PickupConstraints& c, const Eigen::VectorXd& x,
                      double s, int pair) {
  Eigen::VectorXd q(r.dof());
  c.traj().eval(x.data(), s, q.data(), nullptr, nullptr);
  RobotWorkspace ws(r);
  r.forward_kinematics(q.data(), ws);
  const int no = static_cast<int>(pb.obstacles.size());
  const BodySphere& b = pb.body_spheres[pair / no];
  const SphereObstacle& o = pb.obstacles[pair % no];
  return (ws.link_pose[b.link].apply(b.center) - o.center).norm() - b.radius - o.radius;
}

}  // namespace

// A stage with a row subset: some joint rows, collision rows at samples and at instants between
// samples. Its Jacobian and Lagrangian Hessian agree with central differences.
TEST(PickupActiveSet, SubsetRowsHaveExactDerivatives) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 5, example_rho());
  PickupSettings st = fast_settings();
  PickupRowSubset sub;
  sub.joints = {{1, 0, {0, 0, 0}},
                {5, 2, {0, 0, 0}},
                {12, 5, {0, 0, 0}},
                {17, 1, {0, 0, 0}},
                {-1, 2, {0.3, 0.7, 0.0}}};  // the elbow between two grasping samples
  sub.collisions.push_back({3, {0, 0, 0}, 4});
  sub.collisions.push_back({-1, {0.55, 0.0, 0.0}, 7});    // inside [0, T1)
  sub.collisions.push_back({-1, {0.55, 0.0, 0.0}, 12});   // same instant, another pair
  sub.collisions.push_back({-1, {0.3, 0.7, 0.0}, 2});     // inside [T1, T2]
  sub.collisions.push_back({-1, {0.0, 0.45, 0.55}, 14});  // inside (T2, T]
  sub.nonholonomic.push_back({{0.55, 0.0, 0.0}});         // with the collision rows there
  sub.nonholonomic.push_back({{0.0, 0.2, 0.8}});          // an instant of its own
  PickupConstraints c(r, pb, st, 5, &sub);
  PickupConstraints full(r, pb, st, 5);
  EXPECT_LT(c.num_constraints(), full.num_constraints());
  int coll = 0;
  for (const std::string& name : c.row_names()) coll += name.rfind("collision", 0) == 0;
  EXPECT_EQ(coll, 5);
  const Eigen::VectorXd x = perturbed_seed(r, pb, st, c, 11);
  const int m = c.num_constraints();
  std::mt19937 rng(3);
  std::normal_distribution<double> nz(0.0, 1.0);
  Eigen::VectorXd lam(m);
  for (int i = 0; i < m; ++i) lam[i] = 10.0 * nz(rng);
  const Eigen::MatrixXd H = c.dense_hessian(x, lam);
  const double worst_j = test::jacobian_fd_error(c, x), worst_h = test::hessian_fd_error(c, x, lam, H);
  EXPECT_LT(worst_j, 2e-5);
  EXPECT_LT(worst_h, 1e-4);
  // A collision row between samples is the clearance at that instant, minus nothing: its value
  // matches an independent FK evaluation at s = w0 s1 + w1 s2 + w2.
  Eigen::VectorXd g(m);
  c.eval_g(x.data(), g.data());
  const auto names = c.row_names();
  const double s_mid = 0.3 * x[c.idx_s1()] + 0.7 * x[c.idx_s2()];
  bool found = false;
  for (int i = 0; i < m; ++i)
    if (names[i].rfind("collision[2]@", 0) == 0) {
      EXPECT_NEAR(g[i], pair_clearance(r, pb, c, x, s_mid, 2), 1e-12);
      found = true;
    }
  EXPECT_TRUE(found);
  Eigen::VectorXd qm(r.dof());
  c.traj().eval(x.data(), s_mid, qm.data(), nullptr, nullptr);
  found = false;
  for (int i = 0; i < m; ++i)
    if (names[i].rfind("joint_position[2]@", 0) == 0 && std::stoi(names[i].substr(18)) >= c.num_regular_samples()) {
      EXPECT_NEAR(g[i], qm[5], 1e-12);
      found = true;
    }
  EXPECT_TRUE(found);
  // A non-holonomic row between samples is the lateral motion x_s sin phi - y_s cos phi there.
  const double s_nh = 0.2 * x[c.idx_s2()] + 0.8;
  Eigen::VectorXd qs(r.dof());
  c.traj().eval(x.data(), s_nh, qm.data(), qs.data(), nullptr);
  int nh_between = 0;
  bool nh_matched = false;  // one of the two rows is the one at s_nh
  for (int i = 0; i < m; ++i)
    if (names[i].rfind("nonholonomic[0]@", 0) == 0 && std::stoi(names[i].substr(16)) >= c.num_regular_samples()) {
      ++nh_between;
      nh_matched |= std::abs(g[i] - (qs[0] * std::sin(qm[2]) - qs[1] * std::cos(qm[2]))) < 1e-12;
    }
  EXPECT_EQ(nh_between, 2);
  EXPECT_TRUE(nh_matched);
  PickupRowSubset bad;
  bad.collisions.push_back({-1, {0.5, 0.5, 0.0}, 99});
  EXPECT_THROW(PickupConstraints(r, pb, st, 5, &bad), std::invalid_argument);
}

// An obstacle placed where a body is halfway between two samples (and nowhere near any sample):
// the sampled rows do not see it, the dense check does, at an instant inside that gap.
TEST(PickupActiveSet, DenseCheckFindsCollisionsBetweenSamples) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  const Eigen::VectorXd x = heuristic_seed(r, pb, st);
  PickupConstraints probe(r, pb, st, 5);
  // The base sphere's centre midway between regular samples 2 and 3 (both in [0, T1)).
  const int m = st.samples_per_interval;
  const double s_mid = 2.5 / m * x[probe.idx_s1()];
  Eigen::VectorXd q(r.dof());
  probe.traj().eval(x.data(), s_mid, q.data(), nullptr, nullptr);
  RobotWorkspace ws(r);
  r.forward_kinematics(q.data(), ws);
  const BodySphere base = pb.body_spheres[0];
  pb.obstacles.push_back({ws.link_pose[base.link].apply(base.center) + Eigen::Vector3d(0, 0, 0.4), 0.12});
  PickupConstraints c(r, pb, st, 5);
  const int no = static_cast<int>(pb.obstacles.size()), pair = no - 1;  // base sphere x the new obstacle
  // At the samples the new obstacle is clear (the base moves ~1 m between samples) ...
  for (int s : {2, 3}) EXPECT_GT(pair_clearance(r, pb, c, x, double(s) / m * x[c.idx_s1()], pair), st.collision_margin);
  // ... but not in between, and the dense check reports it there.
  EXPECT_LT(pair_clearance(r, pb, c, x, s_mid, pair), 0.0);
  double least = 0.0;
  PickupRowSubset pts = c.dense_points(x, 16, 0.5 * st.collision_margin, 0.5 * st.joint_limit_margin, &least);
  EXPECT_LT(least, 0.0);
  bool between = false;
  for (const auto& p : pts.collisions) {
    if (p.pair != pair) continue;
    EXPECT_EQ(p.sample, -1);
    const double s = p.w[0] * x[c.idx_s1()] + p.w[1] * x[c.idx_s2()] + p.w[2];
    between |= s > 2.0 / m * x[c.idx_s1()] && s < 3.0 / m * x[c.idx_s1()];
  }
  EXPECT_TRUE(between);
  // Stages before 5 carry only the base's collision rows; the dense check follows the stage.
  PickupConstraints s1(r, pb, st, 1);
  for (const auto& p : s1.dense_points(x, 16, 1.0, 0.0).collisions) EXPECT_TRUE(s1.pair_in_stage(p.pair));
  EXPECT_TRUE(s1.pair_in_stage(pair));     // base sphere: a base path constraint
  EXPECT_FALSE(s1.pair_in_stage(no * 4));  // flange sphere: stage 5 only
  EXPECT_TRUE(c.pair_in_stage(no * 4));
}

// A base path that slides sideways between two samples (heading 0, y_s zero at both samples and
// large between them): the sampled non-holonomic rows there read zero, the dense check reports an
// instant inside that gap.
TEST(PickupActiveSet, DenseCheckFindsLateralMotionBetweenSamples) {
  Robot r = load();
  PickupProblem pb = paper_case(r, 1, example_rho());
  PickupSettings st = fast_settings();
  st.dense_nonholonomic = 0.02;  // m/s
  PickupConstraints c(r, pb, st, 1);
  Eigen::VectorXd x = Eigen::VectorXd::Zero(c.num_vars());
  const int m = st.samples_per_interval;
  x[c.idx_s1()] = 0.4;
  x[c.idx_s2()] = 0.5;
  x[c.idx_T()] = 10.0;
  const double a = 2.0 / m * 0.4, b = 3.0 / m * 0.4;  // regular samples 2 and 3, in [0, T1)
  // x = s, y = k (s - a)^2 (s - b)^2 (a quartic; monomial coefficients): y_s = 0 at a and b.
  x[c.traj().offset(0) + 1] = 1.0;
  const double k = 1e5, p[5] = {a * a * b * b, -2 * a * b * (a + b), a * a + 4 * a * b + b * b, -2 * (a + b), 1.0};
  for (int i = 0; i < 5; ++i) x[c.traj().offset(1) + i] = k * p[i];
  Eigen::VectorXd q(r.dof()), qs(r.dof());
  for (double s : {a, b}) {
    c.traj().eval(x.data(), s, q.data(), qs.data(), nullptr);
    EXPECT_NEAR(qs[1], 0.0, 1e-9);
  }
  c.traj().eval(x.data(), 0.5 * (a + b) - 0.25 * (b - a), q.data(), qs.data(), nullptr);
  const double nh_bound =
      st.nonholonomic_tol * ((pb.part_xy - pb.start.head<2>()).norm() + (pb.goal.head<2>() - pb.part_xy).norm());
  ASSERT_GT(std::abs(qs[1]) / x[c.idx_T()], 4 * st.dense_nonholonomic);  // m/s: the slide is well above the threshold
  ASSERT_GT(std::abs(qs[1]), 4 * nh_bound);                              // and the rows' bound
  const PickupRowSubset pts = c.dense_points(x, 16, -1.0, 1e9);
  bool inside = false;
  for (const auto& n : pts.nonholonomic) {
    const double s = n.w[0] * x[c.idx_s1()] + n.w[1] * x[c.idx_s2()] + n.w[2];
    inside |= s > a && s < b;
  }
  EXPECT_TRUE(inside);
  st.dense_nonholonomic = 0.0;  // off: nothing reported
  EXPECT_TRUE(PickupConstraints(r, pb, st, 1).dense_points(x, 16, -1.0, 1e9).nonholonomic.empty());
  st.dense_nonholonomic = 0.02;
  // Joined as rows, they read the lateral motion there, beyond the bound.
  PickupConstraints with(r, pb, st, 1, &pts);
  Eigen::VectorXd g(with.num_constraints()), lo, hi, gl, gu;
  with.eval_g(x.data(), g.data());
  with.bounds(lo, hi, gl, gu);
  const auto names = with.row_names();
  int violated = 0;
  for (int i = 0; i < with.num_constraints(); ++i)
    if (names[i].rfind("nonholonomic", 0) == 0 && std::stoi(names[i].substr(16)) >= with.num_regular_samples())
      violated += g[i] > gu[i];
  EXPECT_GE(violated, 1);
}

// rho >= gamma bounds S_g: nothing above the bound reaches gamma, just below it some S_c does; an unattainable gamma is
// reported as an infeasible status by the stages that carry the probability row.
TEST(PickupActiveSet, SuccessProbabilityBoundsGripperSpeed) {
  RhoPoly rho = example_rho();
  const double cap = rho.sg_upper_bound(0.96, rho.sc_lo, rho.sc_hi);
  ASSERT_TRUE(std::isfinite(cap));
  EXPECT_LT(cap, rho.sg_hi);
  for (double sg = cap + 1e-3; sg <= rho.sg_hi; sg += 0.01)
    for (double sc = rho.sc_lo; sc <= rho.sc_hi; sc += 0.005) EXPECT_LT(rho.value(sg, sc), 0.96);
  bool some_feasible = false;  // the bound is tight: just below it some S_c reaches gamma
  for (double sc = rho.sc_lo; sc <= rho.sc_hi + 1e-12; sc += 0.005) some_feasible |= rho.value(cap - 1e-6, sc) >= 0.96;
  EXPECT_TRUE(some_feasible);
  EXPECT_TRUE(std::isnan(rho.sg_upper_bound(1.5, rho.sc_lo, rho.sc_hi)));
  Robot r = load();
  PaperCaseOptions opt;
  opt.gamma = 0.9999;  // above every coefficient of the surface
  PickupProblem pb = paper_case(r, 1, example_rho(), opt);
  PickupSettings st = fast_settings();
  StageResult res = solve_stage(r, pb, st, 4, heuristic_seed(r, pb, st));
  EXPECT_FALSE(res.success);
  EXPECT_EQ(res.status, SolveStatus::infeasible);
  EXPECT_NE(res.ipopt_status.find("success-probability"), std::string::npos) << res.ipopt_status;
}

// The cases whose trajectories used to cut through obstacles between the samples: the final
// trajectory keeps its clearance under dense re-sampling, and every stage is feasible for the
// full row set (not only for the active rows it was solved with).
TEST(PickupActiveSet, FinalTrajectoriesAreCollisionFreeBetweenSamples) {
  Robot r = load();
  PickupSettings st;  // the benchmark's settings (m = 8)
  for (int case_id : {4, 6}) {
    PickupProblem pb = paper_case(r, case_id, example_rho());
    PickupResult res = solve_successive(r, pb, st);
    ASSERT_TRUE(res.success) << "case " << case_id << ": " << res.status << " " << res.stages.back().ipopt_status;
    for (const StageResult& s : res.stages) {
      EXPECT_LT(PickupConstraints(r, pb, st, s.stage).max_violation(s.x), 1e-4) << "stage " << s.stage;
      EXPECT_GE(s.rounds, 1);
    }
    const PickupMetrics m = evaluate_pickup(r, pb, res, 4001);
    EXPECT_GE(m.min_clearance, 0.0) << "case " << case_id;
    EXPECT_LT(m.pose_error_position, 1e-6);
    EXPECT_GE(m.success_probability, pb.gamma - 1e-6);
  }
}

// The direct track (all constraints from the stage-1 solution) is returned only when it is shorter
// than the five stages' solution. In case 5 the stages from the single IK seed commit the arm to a
// configuration that ends at T = 13.2 s; the direct solve finds 12.65 s (measured).
TEST(PickupActiveSet, DirectTrackReturnsTheShorterFeasibleSolution) {
  Robot r = load();
  PickupSettings st;  // the benchmark's settings (m = 8), one arm seed (the second one beats both)
  st.arm_seeds = 1;
  PickupProblem pb = paper_case(r, 5, example_rho());
  st.direct_track = false;
  const PickupResult staged = solve_successive(r, pb, st);
  ASSERT_TRUE(staged.success) << staged.status;
  EXPECT_EQ(staged.direct.status, SolveStatus::not_run);
  EXPECT_FALSE(staged.direct_chosen);
  st.direct_track = true;
  const PickupResult res = solve_successive(r, pb, st);
  ASSERT_TRUE(res.success) << res.status;
  ASSERT_EQ(res.stages.size(), 5u);  // the stage records are the five stages'
  EXPECT_EQ(res.stages.back().objective, staged.T);
  EXPECT_EQ(res.direct.stage, 0);
  ASSERT_TRUE(res.direct.success) << res.direct.status << " " << res.direct.ipopt_status;
  EXPECT_TRUE(res.direct_chosen);
  EXPECT_LT(res.T, staged.T * 0.99);
  EXPECT_EQ(res.T, res.direct.objective);
  EXPECT_LT(PickupConstraints(r, pb, st, 0).max_violation(res.x), 1e-4);
  const PickupMetrics m = evaluate_pickup(r, pb, res, 4001);
  EXPECT_GE(m.min_clearance, 0.0);
  EXPECT_LT(m.pose_error_position, 1e-6);
  EXPECT_GE(m.success_probability, pb.gamma - 1e-6);
  EXPECT_GT(res.total_cpu_seconds, res.direct.cpu_seconds);  // the direct solve is counted
  // A case where the direct solve fails (case 6: Ipopt reports it infeasible) keeps the staged solution.
  PickupProblem pb6 = paper_case(r, 6, example_rho());
  const PickupResult res6 = solve_successive(r, pb6, st);
  ASSERT_TRUE(res6.success) << res6.status;
  EXPECT_FALSE(res6.direct.success);
  EXPECT_FALSE(res6.direct_chosen);
  EXPECT_EQ(res6.T, res6.stages.back().objective);
  EXPECT_EQ(res6.x, res6.stages.back().x);
}
