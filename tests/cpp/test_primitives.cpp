// Solid primitives: closed-form signed distances against hand-computed values, gradients
// against finite differences, in a SceneSdf (direct and merged) and in the FCL checker.
#include <cmath>
#include <memory>
#include <random>

#include <gtest/gtest.h>

#include "pickplan/geometry/collision.hpp"
#include "pickplan/geometry/primitives.hpp"
#include "pickplan/geometry/sdf.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

Transform posed(double angle, const Eigen::Vector3d& axis, const Eigen::Vector3d& p) {
  Transform T;
  T.R = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.p = p;
  return T;
}

void expect_gradient_matches_differences(const Primitive& prim, const Eigen::Vector3d& p) {
  Eigen::Vector3d g;
  prim.signed_distance(p, &g);
  const double h = 1e-6;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    e[a] = h;
    const double fd = (prim.signed_distance(p + e) - prim.signed_distance(p - e)) / (2 * h);
    EXPECT_NEAR(g[a], fd, 1e-5) << "axis " << a << " at " << p.transpose();
  }
}

}  // namespace

TEST(Primitives, BoxDistancesMatchHandComputedValues) {
  const Primitive box = Primitive::box({0.4, 0.2, 0.1});                           // half extents 0.2, 0.1, 0.05
  EXPECT_NEAR(box.signed_distance({0.5, 0.0, 0.0}), 0.3, 1e-15);                   // off a face
  EXPECT_NEAR(box.signed_distance({0.3, 0.2, 0.0}), std::hypot(0.1, 0.1), 1e-15);  // off an edge
  EXPECT_NEAR(box.signed_distance({-0.23, 0.14, -0.1}), std::sqrt(0.03 * 0.03 + 0.04 * 0.04 + 0.05 * 0.05), 1e-15);
  EXPECT_NEAR(box.signed_distance({0.0, 0.0, 0.0}), -0.05, 1e-15);    // nearest face: z
  EXPECT_NEAR(box.signed_distance({0.15, 0.02, 0.0}), -0.05, 1e-15);  // x and z tie
  EXPECT_NEAR(box.signed_distance({0.19, 0.0, 0.01}), -0.01, 1e-15);
}

TEST(Primitives, CylinderDistancesMatchHandComputedValues) {
  const Primitive cyl = Primitive::cylinder(0.03, 0.14);              // MoveIt's can: radius 3 cm, 14 cm tall
  EXPECT_NEAR(cyl.signed_distance({0.05, 0.0, 0.0}), 0.02, 1e-15);    // radial
  EXPECT_NEAR(cyl.signed_distance({0.03, 0.04, 0.01}), 0.02, 1e-15);  // radial, off-axis direction
  EXPECT_NEAR(cyl.signed_distance({0.0, 0.01, 0.1}), 0.03, 1e-15);    // above the cap
  EXPECT_NEAR(cyl.signed_distance({0.06, 0.0, -0.11}), std::hypot(0.03, 0.04), 1e-15);  // off the rim
  EXPECT_NEAR(cyl.signed_distance({0.0, 0.0, 0.0}), -0.03, 1e-15);                      // the wall is nearest
  EXPECT_NEAR(cyl.signed_distance({0.0, 0.0, 0.065}), -0.005, 1e-15);                   // the cap is nearest
  const Primitive sphere = Primitive::sphere(0.1);
  EXPECT_NEAR(sphere.signed_distance({0.1, 0.2, 0.2}), 0.2, 1e-15);
  EXPECT_NEAR(sphere.signed_distance({0.0, 0.03, 0.04}), -0.05, 1e-15);
}

TEST(Primitives, GradientsAreUnitAndMatchFiniteDifferences) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-0.3, 0.3);
  for (const Primitive& prim :
       {Primitive::box({0.4, 0.2, 0.1}), Primitive::cylinder(0.05, 0.2), Primitive::sphere(0.08)}) {
    for (int i = 0; i < 200; ++i) {
      const Eigen::Vector3d p(u(rng), u(rng), u(rng));
      Eigen::Vector3d g;
      prim.signed_distance(p, &g);
      EXPECT_NEAR(g.norm(), 1.0, 1e-12);
      expect_gradient_matches_differences(prim, p);  // random points: never on a ridge
    }
  }
}

TEST(Primitives, BadDimensionsThrow) {
  EXPECT_THROW(Primitive::box({0.1, 0.0, 0.1}).validate("box"), std::invalid_argument);
  EXPECT_THROW(Primitive::cylinder(0.1, NAN).validate("can"), std::invalid_argument);
  EXPECT_THROW(Primitive::sphere(-1).validate("ball"), std::invalid_argument);
  SceneSdf scene;
  EXPECT_THROW(scene.add_primitive(Primitive::sphere(0), Transform{}), std::invalid_argument);
}

TEST(Primitives, SceneSdfAnswersInClosedFormAndMergedWithinResolution) {
  SceneSdf scene;
  const Primitive board = Primitive::box({0.6, 0.4, 0.02});
  const Primitive can = Primitive::cylinder(0.03, 0.14);
  const Transform T_board = posed(0.4, {0.2, 0.1, 1}, {0.5, 0.0, 0.3});
  const Transform T_can = posed(-0.5, {0, 0, 1}, {0.5, 0.1, 0.38});
  scene.add_primitive(board, T_board);
  scene.add_primitive(can, T_can);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0.1, 0.9), uy(-0.4, 0.4), uz(0.1, 0.6);
  const double cutoff = 0.2;
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 500; ++i) points.emplace_back(ux(rng), uy(rng), uz(rng));
  for (const auto& x : points) {
    const double expected = std::min(
        {cutoff, board.signed_distance(T_board.inverse().apply(x)), can.signed_distance(T_can.inverse().apply(x))});
    Eigen::Vector3d g;
    EXPECT_NEAR(scene.distance(x, &g, cutoff), expected, 1e-12);
  }
  scene.merge(0, MergedSdfSettings{0.01, cutoff, 4});
  for (const auto& x : points) {
    const double exact = scene.distance_unmerged(x, nullptr, cutoff);
    // Trilinear interpolation of a 1-Lipschitz field: within half a cell diagonal.
    EXPECT_NEAR(scene.distance(x, nullptr, cutoff), exact, 0.5 * std::sqrt(3.0) * 0.01);
  }
}

TEST(Primitives, CheckerTakesSolidPrimitives) {
  Robot r = Robot::from_urdf_file(kData + "/mixed_arm.urdf");
  // Only the root box l0: 0.2 x 0.2 x 0.1 centred at the origin, never moves.
  std::vector<LinkMesh> root{{"l0", link_collision_mesh(r, r.link_index("l0"))}};
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  auto make = [&](const Primitive& p, const Transform& T) {
    std::vector<SceneObject> objs{
        {"obstacle", TriangleMesh{}, T, std::make_shared<const CollisionShape>(p, "obstacle")}};
    return CollisionChecker(r, root, objs);
  };
  // A cylinder standing 3 cm off the box's +x face: its exact distance (no tessellation).
  EXPECT_NEAR(make(Primitive::cylinder(0.05, 0.3), posed(0, {0, 0, 1}, {0.1 + 0.03 + 0.05, 0, 0})).min_distance(q),
              0.03, 1e-6);
  // A sphere off the corner (0.1, 0.1, 0.05).
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, 2).normalized();
  EXPECT_NEAR(
      make(Primitive::sphere(0.04), posed(0, {0, 0, 1}, Eigen::Vector3d(0.1, 0.1, 0.05) + 0.065 * dir)).min_distance(q),
      0.025, 1e-6);
  // A board 1 cm into the box from above: a penetration depth, as against the table.
  CollisionChecker hit = make(Primitive::box({1, 1, 0.02}), posed(0, {0, 0, 1}, {0, 0, 0.05 + 0.01 - 0.01}));
  EXPECT_TRUE(hit.in_collision(q));
  EXPECT_NEAR(hit.min_distance(q), -0.01, 1e-6);
  // The root box entirely inside a big solid box: no triangle crosses its surface, yet it collides.
  EXPECT_TRUE(make(Primitive::box({2, 2, 2}), Transform{}).in_collision(q));
  // A small sphere entirely inside the root box's mesh: found by containment.
  EXPECT_TRUE(make(Primitive::sphere(0.01), posed(0, {0, 0, 1}, {0.02, 0, 0})).in_collision(q));
  EXPECT_THROW(make(Primitive::box({1, 0, 1}), Transform{}), std::invalid_argument);
}
