// A link attached to a robot (the object a hand holds, Robot::with_attached_link) against independent
// truth: its pose is the parent's pose times the attachment, exactly; its Jacobians are those of the
// same points on the parent; CHOMP's cost and gradient of points on it equal those of the same points
// given on the parent; FCL sees a mesh on it where the parent alone touches nothing.
#include <cmath>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "mesh_fixtures.hpp"
#include "pickplan/geometry/collision.hpp"
#include "pickplan/omg/chomp.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;
namespace test = pickplan::test;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

Transform attachment() {  // a rigid, non-trivial grasp: rotated and offset
  Transform T;
  T.R = axis_angle(Eigen::Vector3d(0.3, -1.0, 0.4).normalized(), 1.1);
  T.p = Eigen::Vector3d(0.04, -0.02, 0.11);
  return T;
}

Eigen::VectorXd random_q(const Robot& r, std::mt19937& rng) {
  Eigen::VectorXd q(r.dof());
  for (int j = 0; j < r.dof(); ++j) {
    const double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    const double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

}  // namespace

TEST(AttachedLink, PoseIsTheParentsTimesTheAttachmentAndJacobiansAgree) {
  const Robot base = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  const Robot r = base.with_attached_link("held", "l4", attachment());
  ASSERT_EQ(r.num_links(), base.num_links() + 1);
  ASSERT_EQ(r.dof(), base.dof());
  const int held = r.link_index("held"), l4 = r.link_index("l4");
  EXPECT_EQ(held, base.num_links());  // appended: every other link keeps its index
  std::mt19937 rng(3);
  RobotWorkspace ws(r), wb(base);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, r.dof()), Jp(6, r.dof());
  for (int trial = 0; trial < 100; ++trial) {
    const Eigen::VectorXd q = random_q(r, rng);
    r.forward_kinematics(q.data(), ws);
    base.forward_kinematics(q.data(), wb);
    for (int l = 0; l < base.num_links(); ++l)
      EXPECT_EQ((ws.link_pose[l].matrix() - wb.link_pose[l].matrix()).cwiseAbs().maxCoeff(), 0.0);
    const Transform expected = wb.link_pose[l4] * attachment();
    EXPECT_LT((ws.link_pose[held].matrix() - expected.matrix()).cwiseAbs().maxCoeff(), 1e-14);
    const Eigen::Vector3d p = Eigen::Vector3d::Random() * 0.1;
    r.point_jacobian(ws, held, p, J);
    base.point_jacobian(wb, l4, attachment().apply(p), Jp);
    EXPECT_LT((J - Jp).cwiseAbs().maxCoeff(), 1e-13);
    for (int k = 0; k < r.dof(); ++k) EXPECT_EQ(r.moves(k, held), r.moves(k, l4));
  }
}

TEST(AttachedLink, ChompCostOfPointsOnItEqualsTheSamePointsOnTheParent) {
  auto base = std::make_shared<Robot>(Robot::from_urdf_file(kData + "/mixed_arm.urdf"));
  auto r = std::make_shared<Robot>(base->with_attached_link("held", "l4", attachment()));
  // A box the held points pass through half-way along the path; the arm's own points are none.
  Eigen::VectorXd q0(r->dof()), q1(r->dof());
  q0 << -0.6, -0.1, 0.3, -0.2, 0.1;
  q1 << 0.7, 0.15, -0.4, 0.3, -0.2;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-0.04, 0.04);
  BodyPoints on_held, on_parent;
  for (int k = 0; k < 40; ++k) {
    const Eigen::Vector3d p(u(rng), u(rng), u(rng));
    on_held.link.push_back(r->link_index("held"));
    on_held.points.conservativeResize(k + 1, 3);
    on_held.points.row(k) = p.transpose();
    on_parent.link.push_back(r->link_index("l4"));
    on_parent.points.conservativeResize(k + 1, 3);
    on_parent.points.row(k) = attachment().apply(p).transpose();
  }
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d::Constant(0.1), V, F);
  auto grid = std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.15}));
  RobotWorkspace ws(*r);
  const Eigen::VectorXd mid = 0.5 * (q0 + q1);
  r->forward_kinematics(mid.data(), ws);
  Transform pose;
  pose.p = ws.link_pose[r->link_index("held")].p;
  auto scene = std::make_shared<SceneSdf>();
  scene->add_object(grid, pose);
  ChompSettings s;  // every term, no clipping
  s.n = 10, s.duration = 1.0, s.epsilon = 0.1, s.top_k = 0, s.clip_gradient = 0;
  ChompProblem held(r, scene, on_held, s), parent(base, scene, on_parent, s);
  ChompWorkspace wh(held), wp(parent);
  Trajectory xi(s.n, r->dof());
  for (int t = 0; t < s.n; ++t) xi.row(t) = (q0 + (t + 1.0) / s.n * (q1 - q0)).transpose();
  Trajectory gh, gp;
  const ObjectiveTerms th = held.objective(xi, q0, 2, &gh, wh), tp = parent.objective(xi, q0, 2, &gp, wp);
  ASSERT_GT(th.colliding_points, 0);  // the held points go through the box
  EXPECT_NEAR(th.total, tp.total, 1e-12 * (1 + tp.total));
  EXPECT_EQ(th.colliding_points, tp.colliding_points);
  EXPECT_LT((gh - gp).cwiseAbs().maxCoeff(), 1e-10 * (1 + gp.cwiseAbs().maxCoeff()));
}

TEST(AttachedLink, CollisionCheckerSeesAMeshOnItByItsName) {
  const Robot base = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  Transform grip;
  grip.p = Eigen::Vector3d(0, 0, 0.3);  // a 0.1 m cube 0.3 m beyond the l4 sphere
  const Robot r = base.with_attached_link("held", "l4", grip);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  RobotWorkspace ws(r);
  r.forward_kinematics(q.data(), ws);
  TriangleMesh cube;
  test::box_mesh(Eigen::Vector3d::Constant(0.1), cube.vertices, cube.faces);
  TriangleMesh sphere = link_collision_mesh(r, r.link_index("l4"));
  // An obstacle where the held cube is, far from the arm's own l4 sphere.
  SceneObject obstacle{"obstacle", cube, ws.link_pose[r.link_index("held")]};
  std::vector<LinkMesh> arm_only{{"l4", sphere}}, with_held{{"l4", sphere}, {"held", cube}};
  EXPECT_FALSE(CollisionChecker(r, arm_only, {obstacle}).in_collision(q));
  EXPECT_TRUE(CollisionChecker(r, with_held, {obstacle}).in_collision(q));
  CollisionSettings allowed;
  allowed.allowed_pairs = {{"held", "obstacle"}};
  EXPECT_FALSE(CollisionChecker(r, with_held, {obstacle}, {}, allowed).in_collision(q));
}

TEST(AttachedLink, BadInputThrowsNamingTheProblem) {
  const Robot r = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  EXPECT_THROW(r.with_attached_link("l2", "l4", Transform{}), std::invalid_argument);      // name taken
  EXPECT_THROW(r.with_attached_link("held", "nope", Transform{}), std::invalid_argument);  // no parent
  EXPECT_THROW(r.with_attached_link("", "l4", Transform{}), std::invalid_argument);
  Transform sheared;
  sheared.R(0, 1) = 0.3;
  EXPECT_THROW(r.with_attached_link("held", "l4", sheared), std::invalid_argument);
}
