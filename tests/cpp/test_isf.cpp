// C-Space ISF (OMG Sec. III-E, Algorithm 1) on the floating hand and a 6 cm cube: the cost
// gradient against finite differences, a penetrating palm pushed out (checked against the exact
// box distance, not the SDF), and contacts pulled onto the faces where symmetry puts them.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "arm_fixtures.hpp"
#include "mesh_fixtures.hpp"
#include "pickplan/omg/isf.hpp"
#include "pickplan/omg/omg_loop.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;
using test::kPalmCenter;
using test::kPalmSize;

namespace {

constexpr double kHalfCube = 0.03;

struct IsfCase {
  std::shared_ptr<const Robot> robot = test::floating_hand();
  int hand = robot->link_index("hand");
  Vertices contacts, normals;  // finger pads at x = +-3 cm, normals pointing inward
  std::shared_ptr<SceneSdf> hand_sdf = std::make_shared<SceneSdf>();
  Vertices cube_points, cube_normals;  // the cube's surface, 1 cm apart, outward normals
  std::shared_ptr<SceneSdf> scene = std::make_shared<SceneSdf>();
  BodyPoints body;

  IsfCase() {
    contacts.resize(2, 3);
    contacts << kHalfCube, 0, 0, -kHalfCube, 0, 0;
    normals.resize(2, 3);
    normals << -1, 0, 0, 1, 0, 0;
    Vertices V;
    Faces F;
    test::box_mesh(kPalmSize, V, F);
    Transform palm;
    palm.p = kPalmCenter;
    hand_sdf->add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.004, 0.02})), palm);
    std::vector<Eigen::Vector3d> pts, nrm;
    for (int axis = 0; axis < 3; ++axis)
      for (double side : {-1.0, 1.0})
        for (int i = -3; i <= 3; ++i)
          for (int j = -3; j <= 3; ++j) {
            Eigen::Vector3d p, n = Eigen::Vector3d::Zero();
            p[axis] = side * kHalfCube;
            p[(axis + 1) % 3] = 0.01 * i;
            p[(axis + 2) % 3] = 0.01 * j;
            n[axis] = side;
            pts.push_back(p);
            nrm.push_back(n);
          }
    cube_points.resize(pts.size(), 3);
    cube_normals.resize(pts.size(), 3);
    for (size_t k = 0; k < pts.size(); ++k) {
      cube_points.row(k) = pts[k].transpose();
      cube_normals.row(k) = nrm[k].transpose();
    }
  }

  // An arm obstacle (a 5 cm box) 12 cm beside the hand and four body points on the palm's corners.
  void add_obstacle() {
    Vertices V;
    Faces F;
    test::box_mesh(Eigen::Vector3d::Constant(0.05), V, F);
    Transform pose;
    pose.p = Eigen::Vector3d(0.0, 0.14, -0.05);
    scene->add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.1})), pose);
    body.points.resize(4, 3);
    body.points << 0.05, 0.05, -0.05, -0.05, 0.05, -0.05, 0.05, 0.05, -0.07, -0.05, 0.05, -0.07;
    body.link.assign(4, hand);
  }

  GraspRefiner refiner(IsfSettings s = {}) const {
    return GraspRefiner(robot, hand, contacts, normals, hand_sdf, cube_points, cube_normals, scene, body, 0, s);
  }

  // Deepest penetration of a cube surface point into the palm box at q (exact box distance).
  double palm_penetration(const Eigen::VectorXd& q) const {
    RobotWorkspace ws(*robot);
    robot->forward_kinematics(q.data(), ws);
    const Transform inv = ws.link_pose[hand].inverse();
    double worst = 0;
    for (Eigen::Index k = 0; k < cube_points.rows(); ++k) {
      const Eigen::Vector3d local = inv.apply(cube_points.row(k).transpose()) - kPalmCenter;
      worst = std::min(worst, box_signed_distance(local, kPalmSize / 2, nullptr));
    }
    return worst;
  }
};

Eigen::VectorXd config(double x, double y, double z, double yaw = 0, double pitch = 0, double roll = 0) {
  Eigen::VectorXd q(6);
  q << x, y, z, yaw, pitch, roll;
  return q;
}

}  // namespace

TEST(Isf, CostGradientMatchesFiniteDifferences) {
  IsfCase c;
  c.add_obstacle();
  IsfSettings s;
  s.beta = 0.1;  // so the arm obstacle term weighs in the gradient
  const GraspRefiner r = c.refiner(s);
  const Eigen::VectorXd q = config(0.004, -0.003, 0.012, 0.1, -0.06, 0.08);
  Eigen::VectorXd grad;
  const GraspTerms t = r.cost(q, &grad);
  ASSERT_EQ(t.matched, 2);
  ASSERT_GT(t.pml, 0.0);
  ASSERT_GT(t.align, 0.0);
  ASSERT_GT(t.hand, 0.0);
  ASSERT_GT(t.obstacle, 0.0);
  EXPECT_NEAR(t.total, t.pml + s.alpha * t.align + s.gamma * (t.hand + s.beta * t.obstacle), 1e-12 * t.total);
  const double h = 1e-7;
  for (int j = 0; j < 6; ++j) {
    Eigen::VectorXd qp = q, qm = q;
    qp[j] += h;
    qm[j] -= h;
    const double fd = (r.cost(qp, nullptr).total - r.cost(qm, nullptr).total) / (2 * h);
    EXPECT_NEAR(grad[j], fd, 1e-4 * (1 + grad.cwiseAbs().maxCoeff())) << "joint " << j;
  }
}

TEST(Isf, PenetratingPalmIsPushedOut) {
  IsfCase c;
  const GraspRefiner r = c.refiner();
  const Eigen::VectorXd q = config(0, 0, 0.012);  // the palm's top 1.2 cm inside the cube
  ASSERT_LT(c.palm_penetration(q), -0.01);
  GraspTerms before = r.cost(q, nullptr), after;
  ASSERT_GT(before.hand, 0.0);
  const Eigen::VectorXd out = r.refine(q, 20, &after);
  EXPECT_GE(c.palm_penetration(out), -0.002);  // out, up to the SDF grid's resolution
  EXPECT_LT(after.total, before.total);
  EXPECT_LT(after.hand, 0.1 * before.hand);
  EXPECT_LT(out[2], 0.0);                                // by moving away from the cube (down), not through it
  EXPECT_LT(std::abs(out[0]) + std::abs(out[1]), 1e-3);  // the fit keeps the fingers on the faces
}

TEST(Isf, ContactsArePulledOntoTheFaces) {
  IsfCase c;
  const GraspRefiner r = c.refiner();
  const Eigen::VectorXd q = config(0.005, 0, -0.02);  // one pad 5 mm outside, one 5 mm inside; palm clear
  GraspTerms before = r.cost(q, nullptr), after;
  ASSERT_NEAR(before.pml, 0.5, 1e-9);  // two residuals of half a length unit (1 cm)
  ASSERT_EQ(before.hand, 0.0);
  const Eigen::VectorXd out = r.refine(q, 30, &after);
  EXPECT_NEAR(out[0], 0.0, 1e-3);  // centred between the faces, as symmetry demands
  EXPECT_LT(after.pml, 0.01);
  // Every step is accepted only when f_grasp decreases.
  Eigen::VectorXd cur = q;
  double f = before.total;
  for (int i = 0; i < 5; ++i) {
    GraspTerms t;
    cur = r.step(cur, &t);
    EXPECT_LE(t.total, f);
    f = t.total;
  }
}

TEST(Isf, BadInputThrowsNamingTheProblem) {
  using test::expect_invalid_argument;
  IsfCase c;
  c.add_obstacle();
  const GraspRefiner r = c.refiner();
  expect_invalid_argument([&] { r.cost(Eigen::VectorXd::Zero(5), nullptr); }, "expected 6 joint values, got 5");
  expect_invalid_argument([&] { r.refine(Eigen::VectorXd::Zero(7), 1); }, "expected 6 joint values, got 7");
  auto build = [&](const IsfCase& k) { k.refiner(); };
  IsfCase bad = c;
  bad.normals = c.normals.topRows(1);
  expect_invalid_argument([&] { build(bad); }, "ISF contact normals: expected 2 rows, got 1");
  bad = c;
  bad.cube_normals = c.cube_normals.topRows(5);
  expect_invalid_argument([&] { build(bad); }, "ISF object normals: expected 294 rows, got 5");
  bad = c;
  bad.body.link.pop_back();
  expect_invalid_argument([&] { build(bad); }, "ISF body points: links: expected 4 entries, got 3");
  bad = c;
  bad.body.link[2] = 42;
  expect_invalid_argument([&] { build(bad); }, "link index 42 out of range");
  bad = c;
  bad.normals(0, 1) = NAN;
  expect_invalid_argument([&] { build(bad); }, "ISF contact normals: value 1");
  bad = c;
  bad.hand = 99;
  expect_invalid_argument([&] { build(bad); }, "hand link out of range");
  IsfSettings s;
  s.active = {true, true};
  expect_invalid_argument([&] { c.refiner(s); }, "active joint mask: expected 6 entries, got 2");
}

TEST(Isf, StepsDoNotPressTheFingersDeeperIntoTheSupport) {
  // The case above pulls the hand from x = 5 mm to x = 0. A support plane x = 5 mm whose free side is
  // +x (a "finger" vertex at the hand origin touching it) forbids exactly that motion.
  IsfCase c;
  GraspRefiner r = c.refiner();
  const Eigen::VectorXd q = config(0.005, 0, -0.02);
  EXPECT_TRUE(std::isinf(r.support_depth(q)) && r.support_depth(q) < 0);  // no support yet
  SupportPlane support;
  support.finger_vertices = Vertices::Zero(1, 3);
  support.normal = Eigen::Vector3d::UnitX();
  support.offset = 0.005;
  r.set_support(support);
  EXPECT_NEAR(r.support_depth(q), 0.0, 1e-12);
  EXPECT_NEAR(r.support_depth(config(0.002, 0.01, 0.0)), 0.003, 1e-12);  // exact: 3 mm past the plane
  const Eigen::VectorXd out = r.refine(q, 30);
  EXPECT_LE(r.support_depth(out), 1e-9);
  EXPECT_GT(out[0], 0.005 - 1e-6);
  support.offset = 0.006;  // starting 1 mm in: it may stay as deep, not go deeper
  r.set_support(support);
  EXPECT_LE(r.support_depth(r.refine(q, 30)), 0.001 + 1e-9);
  support.normal = Eigen::Vector3d(0, 0, 2);
  test::expect_invalid_argument([&] { r.set_support(support); }, "unit vector");
}

// A refiner placed again (the target moved) equals one built at the new place: the shared k-d tree,
// queried through the motion, finds the same nearest points; a motion that is not the points' own throws.
TEST(Isf, PlacedAgainEqualsBuiltThere) {
  IsfCase c;
  const GraspRefiner first = c.refiner();
  Transform motion;
  motion.R = axis_angle(Eigen::Vector3d::UnitZ(), 0.3);
  motion.p = Eigen::Vector3d(0.02, -0.01, 0.0);
  Vertices pts(c.cube_points.rows(), 3), nrm(c.cube_normals.rows(), 3);
  for (Eigen::Index k = 0; k < pts.rows(); ++k) {
    pts.row(k) = motion.apply(c.cube_points.row(k).transpose()).transpose();
    nrm.row(k) = (motion.R * c.cube_normals.row(k).transpose()).transpose();
  }
  const auto moved = first.with_object(pts, nrm, motion);
  const GraspRefiner built(c.robot, c.hand, c.contacts, c.normals, c.hand_sdf, pts, nrm, c.scene, c.body, 0, {});
  // The hand where it held the cube before, moved with it (yaw and shift as the target), and a bit off.
  for (const Eigen::VectorXd& q : {config(0.02, -0.01, -0.02, 0.3), config(0.025, -0.012, -0.01, 0.35, 0.05)}) {
    Eigen::VectorXd g_moved, g_built;
    const GraspTerms a = moved->cost(q, &g_moved), b = built.cost(q, &g_built);
    ASSERT_GT(b.matched, 0);
    EXPECT_EQ(a.matched, b.matched);
    EXPECT_NEAR(a.total, b.total, 1e-12 * (1 + b.total));
    EXPECT_LT((g_moved - g_built).cwiseAbs().maxCoeff(), 1e-9 * (1 + g_built.cwiseAbs().maxCoeff()));
  }
  Transform wrong = motion;
  wrong.p.x() += 1e-3;
  EXPECT_THROW(first.with_object(pts, nrm, wrong), std::invalid_argument);
}

// The loop's goal book takes an ISF refinement with the goal's approach shifted alike, and that approach is
// pinned from then on: shifted past a joint limit it could never be executed, so the refinement is not taken.
TEST(GoalBook, RefinementShiftingTheApproachPastAJointLimitIsNotTaken) {
  IsfCase c;
  const GraspRefiner r = c.refiner();
  Trajectory goals(1, 6);
  goals.row(0) = config(0, 0, 0.012).transpose();  // the palm 1.2 cm into the cube: ISF moves it down
  auto approach_from = [&](double z) {
    Trajectory tail(2, 6);
    tail.row(0) = config(0, 0, z).transpose();
    tail.row(1) = goals.row(0);
    return tail;
  };
  GoalBook free(*c.robot, c.hand, goals, {approach_from(-0.4)}, {0});
  const auto [g, added] = free.refine(0, r, 20, 0.05);
  ASSERT_TRUE(added);
  EXPECT_LT(free.tail(g)(0, 2), -0.41);  // shifted down by more than 1 cm
  // 5 mm above the z joint's lower limit (-0.5 m): the same shift would take the approach past it
  GoalBook edge(*c.robot, c.hand, goals, {approach_from(-0.495)}, {0});
  const auto [g2, added2] = edge.refine(0, r, 20, 0.05);
  EXPECT_FALSE(added2);
  EXPECT_EQ(g2, 0);
  EXPECT_EQ(edge.size(), 1);
  EXPECT_TRUE(edge.stalled(0));
  EXPECT_EQ(edge.tail(0), approach_from(-0.495));
}
