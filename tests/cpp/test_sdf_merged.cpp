// The merged scene grid and the cheap lower bounds against the per-object grids (the reference)
// and exact box geometry.
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "mesh_fixtures.hpp"
#include "pickplan/geometry/sdf.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
namespace test = pickplan::test;

namespace {

// Three rotated boxes on a table: rotated so the world-aligned merged grid resamples them.
SceneSdf three_boxes(std::vector<std::pair<Transform, Eigen::Vector3d>>* boxes = nullptr) {
  SceneSdf scene;
  const Eigen::Vector3d sizes[3] = {{0.1, 0.06, 0.2}, {0.05, 0.05, 0.12}, {0.08, 0.12, 0.06}};
  const double yaw[3] = {0.3, -1.1, 2.0};
  const Eigen::Vector3d at[3] = {{0.5, 0.0, 0.1}, {0.6, 0.15, 0.06}, {0.45, -0.2, 0.03}};
  for (int i = 0; i < 3; ++i) {
    Vertices V;
    Faces F;
    test::box_mesh(sizes[i], V, F);
    Transform T;
    T.R = axis_angle(Eigen::Vector3d::UnitZ(), yaw[i]);
    T.p = at[i];
    scene.add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.005, 0.2})), T);
    if (boxes) boxes->push_back({T, sizes[i]});
  }
  Transform table;
  table.p = Eigen::Vector3d(0.5, 0, -0.025);
  scene.set_table(Eigen::Vector3d(1.2, 1.2, 0.05), table);
  return scene;
}

}  // namespace

TEST(MergedSdf, MatchesExactBoxDistancesWithinTheCutoff) {
  std::vector<std::pair<Transform, Eigen::Vector3d>> boxes;
  SceneSdf scene = three_boxes(&boxes);
  scene.merge(0);
  ASSERT_NE(scene.merged(), nullptr);
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> ux(0.2, 0.8), uy(-0.45, 0.35), uz(-0.02, 0.35);
  // Two trilinear resamplings of a 1-Lipschitz field, each off by at most h sqrt(3) / 2.
  const double tol = (0.005 + MergedSdfSettings{}.resolution) * std::sqrt(3.0) / 2;
  int within = 0;
  for (int i = 0; i < 20000; ++i) {
    const Eigen::Vector3d x(ux(rng), uy(rng), uz(rng));
    double exact = x.z();  // table top at z = 0
    for (const auto& [T, size] : boxes)
      exact = std::min(exact, box_signed_distance(T.inverse().apply(x), size / 2, nullptr));
    const double d = scene.distance(x, nullptr, 0.2);
    if (exact < 0.2 - tol) {
      EXPECT_NEAR(d, exact, tol) << x.transpose();
      ++within;
    } else {
      EXPECT_GE(d, std::min(exact, 0.2) - tol);
    }
  }
  EXPECT_GT(within, 5000);
}

TEST(MergedSdf, AgreesWithThePerObjectGridsAndFallsBackForOtherMasks) {
  SceneSdf scene = three_boxes();
  SceneSdf reference = scene;
  scene.merge(0b010);  // the second box excluded, as a planning target would be
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> ux(0.2, 0.8), uy(-0.45, 0.35), uz(0.0, 0.35);
  for (int i = 0; i < 5000; ++i) {
    const Eigen::Vector3d x(ux(rng), uy(rng), uz(rng));
    Eigen::Vector3d g, gr;
    EXPECT_NEAR(scene.distance(x, &g, 0.2, 0b010), reference.distance(x, &gr, 0.2, 0b010),
                MergedSdfSettings{}.resolution * std::sqrt(3.0) / 2);
    // Another mask or a larger cutoff: bit-identical to the per-object path.
    EXPECT_EQ(scene.distance(x, &g, 0.2, 0), reference.distance(x, &gr, 0.2, 0));
    EXPECT_EQ(scene.distance(x, &g, 0.5, 0b010), reference.distance(x, &gr, 0.5, 0b010));
  }
}

TEST(MergedSdf, GradientIsTheInterpolantDerivative) {
  SceneSdf scene = three_boxes();
  scene.merge(0, {0.005, 0.2, 8});
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> ux(0.3, 0.7), uy(-0.3, 0.3), uz(0.01, 0.3);
  const double h = 1e-7;
  int checked = 0;
  for (int i = 0; i < 3000; ++i) {
    const Eigen::Vector3d x(ux(rng), uy(rng), uz(rng));
    Eigen::Vector3d g;
    const double d = scene.distance(x, &g, 0.2, SceneSdf::kTableBit);
    if (d >= 0.2 - 1e-3) continue;
    for (int a = 0; a < 3; ++a) {
      const double f = (x[a] - scene.merged()->origin()[a]) / 0.005;
      if (std::abs(f - std::round(f)) < 1e-3) continue;  // kink at a node plane
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      e[a] = h;
      const double fd = (scene.distance(x + e, nullptr, 0.2, SceneSdf::kTableBit) -
                         scene.distance(x - e, nullptr, 0.2, SceneSdf::kTableBit)) /
                        (2 * h);
      EXPECT_NEAR(g[a], fd, 1e-5);
      ++checked;
    }
  }
  EXPECT_GT(checked, 2000);
}

TEST(MergedSdf, LowerBoundNeverExceedsTheDistance) {
  for (bool merged : {false, true}) {
    SceneSdf scene = three_boxes();
    if (merged) scene.merge(0);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> ux(-0.5, 1.5), uy(-1.0, 1.0), uz(-0.1, 1.0);
    int useful = 0;
    for (int i = 0; i < 20000; ++i) {
      const Eigen::Vector3d x(ux(rng), uy(rng), uz(rng));
      const double lb = scene.lower_bound(x, 0);
      EXPECT_LE(lb, scene.distance(x, nullptr, 1e9, 0) + 1e-12) << x.transpose() << " merged " << merged;
      if (merged) EXPECT_LE(std::min(lb, 0.2), scene.distance(x, nullptr, 0.2, 0) + 1e-12);
      useful += lb > 0.2;
    }
    EXPECT_GT(useful, 5000);  // far points are recognised as far
  }
}

TEST(MergedSdf, OneGridPerMaskEachEqualToMergingThatMaskAlone) {
  // A planning scene keeps the target out (grasping, metrics) and in (the transit's obstacle cost):
  // with both merged, each query reads its own grid, bit-equal to a scene merged with its mask only.
  SceneSdf both = three_boxes(), only_out = three_boxes(), only_in = three_boxes(), reference = three_boxes();
  both.merge(0b010);
  both.merge(0);
  only_out.merge(0b010);
  only_in.merge(0);
  ASSERT_EQ(both.num_merged(), 2);
  EXPECT_EQ(both.merged()->exclude_mask(), 0b010u);  // the first merged
  EXPECT_EQ(both.merged(0)->exclude_mask(), 0u);
  EXPECT_EQ(both.merged(SceneSdf::kTableBit | 0b010)->exclude_mask(), 0b010u);  // the table bit is not an object
  EXPECT_EQ(both.merged(0b001), nullptr);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.2, 0.8), uy(-0.45, 0.35), uz(0.0, 0.35);
  std::vector<double> X(3 * 4000), d_both(4000), d_one(4000), g_both(3 * 4000), g_one(3 * 4000);
  for (double& v : X) v = 0;
  for (int i = 0; i < 4000; ++i) X[3 * i] = ux(rng), X[3 * i + 1] = uy(rng), X[3 * i + 2] = uz(rng);
  for (const auto& [mask, one] : {std::pair<std::uint64_t, const SceneSdf*>{0b010, &only_out}, {0, &only_in}}) {
    both.distances(X.data(), 4000, d_both.data(), g_both.data(), 0.2, mask);
    one->distances(X.data(), 4000, d_one.data(), g_one.data(), 0.2, mask);
    EXPECT_EQ(d_both, d_one);
    EXPECT_EQ(g_both, g_one);
    for (int i = 0; i < 4000; ++i) {  // and each within the resampling error of the per-object grids
      const Eigen::Map<const Eigen::Vector3d> x(X.data() + 3 * i);
      EXPECT_NEAR(d_both[i], reference.distance(x, nullptr, 0.2, mask),
                  MergedSdfSettings{}.resolution * std::sqrt(3.0) / 2);
      EXPECT_EQ(both.lower_bound(x, mask), one->lower_bound(x, mask));
    }
  }
  // Merging a mask again replaces its grid; more masks than kMaxMerged is an error, not a silent drop.
  both.merge(0, {0.02, 0.2, 4});
  EXPECT_EQ(both.num_merged(), 2);
  EXPECT_EQ(both.merged(0)->settings().resolution, 0.02);
  both.merge(0b001);
  both.merge(0b100);
  EXPECT_THROW(both.merge(0b011), std::invalid_argument);
  EXPECT_EQ(both.num_merged(), SceneSdf::kMaxMerged);
}

TEST(MergedSdf, BadSettingsThrowAndAddingAnObjectDropsTheMergedGrid) {
  SceneSdf scene = three_boxes();
  EXPECT_THROW(scene.merge(0, {0.0, 0.2, 8}), std::invalid_argument);
  EXPECT_THROW(scene.merge(0, {0.005, -1.0, 8}), std::invalid_argument);
  EXPECT_THROW(scene.merge(0, {0.005, 0.2, 0}), std::invalid_argument);
  EXPECT_THROW(scene.merge(0, {std::nan(""), 0.2, 8}), std::invalid_argument);
  scene.merge(0);
  ASSERT_NE(scene.merged(), nullptr);
  Vertices V;
  Faces F;
  test::box_mesh(Eigen::Vector3d(0.05, 0.05, 0.05), V, F);
  scene.add_object(std::make_shared<SdfGrid>(SdfGrid::build(V, F, {0.01, 0.05})), Transform());
  EXPECT_EQ(scene.merged(), nullptr);
  // NaN points never read outside the grid.
  const double nan = std::nan("");
  EXPECT_EQ(SceneSdf(three_boxes()).lower_bound(Eigen::Vector3d(0.5, 0, 0.5)) > 0, true);
  SceneSdf m = three_boxes();
  m.merge(0);
  Eigen::Vector3d g;
  m.distance(Eigen::Vector3d(nan, nan, nan), &g, 0.2, SceneSdf::kTableBit);
}

// Bricks fill on the first lookup that lands in them: lookups from several threads at once
// (racing to fill the same bricks) give the very values one thread gives.
TEST(MergedSdf, LazyBricksFilledByRacingThreadsEqualOneThread) {
  SceneSdf one = three_boxes(), racing = three_boxes();
  one.merge(0);
  racing.merge(0);
  EXPECT_EQ(racing.merged()->num_filled(), 0);
  EXPECT_GT(racing.merged()->num_bricks(), 0);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.2, 0.8), uy(-0.45, 0.35), uz(0.0, 0.35);
  const int n = 4000;
  std::vector<double> points(3 * n);
  for (double& v : points) v = 0;
  for (int i = 0; i < n; ++i) points[3 * i] = ux(rng), points[3 * i + 1] = uy(rng), points[3 * i + 2] = uz(rng);
  std::vector<double> expected(n), expected_grad(3 * n);
  one.distances(points.data(), n, expected.data(), expected_grad.data(), 0.2, 0, true, true);
  const int threads = 4;
  std::vector<std::vector<double>> got(threads, std::vector<double>(n)), got_grad(threads, std::vector<double>(3 * n));
  std::vector<std::thread> pool;
  for (int t = 0; t < threads; ++t)
    pool.emplace_back(
        [&, t] { racing.distances(points.data(), n, got[t].data(), got_grad[t].data(), 0.2, 0, true, true); });
  for (auto& th : pool) th.join();
  for (int t = 0; t < threads; ++t) {
    EXPECT_EQ(got[t], expected);
    EXPECT_EQ(got_grad[t], expected_grad);
  }
  const long filled = racing.merged()->num_filled();
  EXPECT_GT(filled, 0);
  EXPECT_EQ(filled, one.merged()->num_filled());
  EXPECT_LE(filled, racing.merged()->num_bricks());
}
