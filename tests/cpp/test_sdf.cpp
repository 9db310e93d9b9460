#include <random>

#include <gtest/gtest.h>

#include "mesh_fixtures.hpp"
#include "pickplan/geometry/sdf.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
namespace test = pickplan::test;

TEST(Sdf, BoxGridMatchesExactBoxDistance) {
  Vertices V;
  Faces F;
  const Eigen::Vector3d size(0.1, 0.06, 0.04);
  test::box_mesh(size, V, F);
  SdfBuildReport report;
  SdfGrid g = SdfGrid::build(V, F, {0.005, 0.1}, &report);
  // Nodes exactly on a face get split ray votes; their distance is 0, so the sign is moot.
  EXPECT_LT(report.sign_disagreement, 0.01);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-0.12, 0.12);  // inside the grid (margin 0.1)
  const double tol = 0.005 * std::sqrt(3.0) / 2;
  for (int i = 0; i < 5000; ++i) {
    Eigen::Vector3d p(u(rng), u(rng), u(rng));
    const double exact = box_signed_distance(p, size / 2, nullptr);
    EXPECT_NEAR(g.distance(p), exact, tol) << p.transpose();
  }
}

TEST(Sdf, GradientIsTheInterpolantDerivativeInsideAndOutsideTheGrid) {
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d(0.1, 0.1, 0.1), V, F);
  SdfGrid g = SdfGrid::build(V, F, {0.01, 0.03});
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> u(-0.2, 0.2);
  const double h = 1e-7;
  int checked = 0;
  for (int i = 0; i < 2000; ++i) {
    Eigen::Vector3d p(u(rng), u(rng), u(rng)), grad;
    g.distance(p, &grad);
    for (int a = 0; a < 3; ++a) {
      const double f = (p[a] - g.origin()[a]) / g.resolution();
      if (std::abs(f - std::round(f)) < 1e-4) continue;  // kink of the interpolant
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e[a] = h;
      const double fd = (g.distance(p + e) - g.distance(p - e)) / (2 * h);
      EXPECT_NEAR(grad[a], fd, 1e-6);
      ++checked;
    }
  }
  EXPECT_GT(checked, 5000);
}

TEST(Sdf, HoleInTheMeshDoesNotFlipTheSign) {
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d(0.1, 0.1, 0.1), V, F);
  Faces holed = F.bottomRows(F.rows() - 1);
  SdfGrid g = SdfGrid::build(V, holed, {0.01, 0.05});
  EXPECT_LT(g.distance(Eigen::Vector3d::Zero()), -0.04);
  EXPECT_GT(g.distance(Eigen::Vector3d(0.12, 0, 0)), 0.06);
}

TEST(Sdf, SceneTakesMinimumSkipsFarBodiesAndExcludes) {
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d(0.1, 0.1, 0.1), V, F);
  auto grid = std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.05}));
  SceneSdf scene;
  Transform a, b;
  a.p = Eigen::Vector3d(0.5, 0, 0.05);
  b.p = Eigen::Vector3d(0.5, 0.5, 0.05);
  EXPECT_EQ(scene.add_object(grid, a), 0);
  EXPECT_EQ(scene.add_object(grid, b), 1);
  Transform table;
  table.p = Eigen::Vector3d(0.5, 0, -0.025);
  scene.set_table(Eigen::Vector3d(2, 2, 0.05), table);
  Eigen::Vector3d grad;
  const Eigen::Vector3d x(0.5, 0.2, 0.3);
  EXPECT_NEAR(scene.distance(x, &grad, 1e9), std::sqrt(0.15 * 0.15 + 0.2 * 0.2), 0.01);
  EXPECT_NEAR(scene.distance(x, &grad, 1e9, SceneSdf::kTableBit | 1), std::sqrt(0.25 * 0.25 + 0.2 * 0.2), 0.01);
  // Beyond the cutoff: the cutoff itself and a zero gradient.
  EXPECT_EQ(scene.distance(Eigen::Vector3d(5, 5, 5), &grad, 0.2), 0.2);
  EXPECT_EQ(grad.norm(), 0.0);
  // Table top: analytic and exact.
  EXPECT_NEAR(scene.distance(Eigen::Vector3d(0.0, -0.5, 0.02), &grad, 1e9), 0.02, 1e-15);
  EXPECT_NEAR(grad.z(), 1.0, 1e-15);
}

TEST(Sdf, BadInputThrows) {
  Vertices V(0, 3);
  Faces F(0, 3);
  EXPECT_THROW(SdfGrid::build(V, F), std::invalid_argument);
  Vertices V2(3, 3);
  V2.setZero();
  Faces F2(1, 3);
  F2 << 0, 1, 2;
  EXPECT_THROW(SdfGrid::build(V2, F2), std::invalid_argument);  // degenerate
  F2 << 0, 1, 7;
  EXPECT_THROW(SdfGrid::build(V2, F2), std::invalid_argument);  // bad index
  EXPECT_THROW(SdfGrid::from_values(Eigen::Vector3d::Zero(), 0.01, Eigen::Vector3i(2, 2, 2), std::vector<float>(7)),
               std::invalid_argument);
}
