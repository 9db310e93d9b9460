// The depth-image world model: the exact distance transform against brute force, and the fused field
// of a synthetic view (a box on the table plane seen from above) against exact box distances.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "pickplan/perception/depth_field.hpp"

using namespace pickplan::perception;

namespace pickplan {
namespace {

TEST(DepthField, DistanceTransformIsExact) {
  // lines shorter than the transform's 16-line blocks, and longer ones ending in a partial block
  for (const Eigen::Vector3i dims : {Eigen::Vector3i(9, 7, 5), Eigen::Vector3i(37, 11, 13)}) {
    std::mt19937 rng(4);
    std::vector<std::uint8_t> mask(dims.prod());
    for (auto& m : mask) m = (rng() % 97) == 0;
    mask[3] = 1;
    const auto d2 = squared_distance_transform(mask, dims);
    auto at = [&](int i) {
      return Eigen::Vector3i(i % dims.x(), (i / dims.x()) % dims.y(), i / (dims.x() * dims.y()));
    };
    for (int i = 0; i < dims.prod(); ++i) {
      double best = 1e30;
      for (int j = 0; j < dims.prod(); ++j)
        if (mask[j]) best = std::min(best, (at(j) - at(i)).cast<double>().squaredNorm());
      ASSERT_NEAR(d2[i], best, 1e-3) << "voxel " << i << " of " << dims.transpose();
    }
  }
}

// A camera 1 m above the origin looking straight down at a 10 cm cube centred at (0, 0, 0.05).
DepthView top_view(int W = 200, int H = 200, double f = 150.0) {
  DepthView v;
  v.K << f, 0, W / 2.0, 0, f, H / 2.0, 0, 0, 1;
  v.camera_pose.R << 1, 0, 0, 0, -1, 0, 0, 0, -1;  // z down, x along world x, y along world -y
  v.camera_pose.p = Eigen::Vector3d(0, 0, 1.0);
  v.depth.resize(H, W);
  v.target = PixelMask::Zero(H, W);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const double x = (c + 0.5 - W / 2.0) / f, y = -(r + 0.5 - H / 2.0) / f;  // world direction per unit depth
      const bool on_box = std::abs(x * 0.9) <= 0.05 && std::abs(y * 0.9) <= 0.05;
      v.depth(r, c) = static_cast<float>(on_box ? 0.9 : 1.0);
    }
  return v;
}

TEST(DepthField, MatchesExactDistancesAboveABox) {
  DepthFieldSettings s;
  s.lo = Eigen::Vector3d(-0.3, -0.3, -0.05);
  s.hi = Eigen::Vector3d(0.3, 0.3, 0.4);
  s.resolution = 0.01;
  s.has_plane = true;
  const DepthField f = build_depth_field({top_view()}, s);
  ASSERT_GT(f.occupied, 0);
  for (double z : {0.14, 0.18, 0.25}) {  // above the cube's top face (z = 0.1): seen from the camera
    const double d = f.obstacles->distance(Eigen::Vector3d(0.01, -0.02, z));
    EXPECT_NEAR(d, z - 0.1, s.resolution) << "z " << z;
  }
  // beside the cube, under its top face: hidden from a camera straight above only where the cube
  // shadows it; just outside the shadow the field sees the table and the cube's side
  EXPECT_LE(f.obstacles->distance(Eigen::Vector3d(0.0, 0.0, 0.05)), 0.0);  // inside the cube
}

TEST(DepthField, NodeValuesAreExactDistancesOfTheOccupiedSet) {
  // every node against brute force over the occupied set the field's signs give: outside, the
  // distance to the nearest occupied node less half a voxel (capped at 1 m); inside, minus the
  // distance to the nearest free node less half a voxel (the inside transform runs on a sub-box)
  DepthFieldSettings s;
  s.lo = Eigen::Vector3d(-0.15, -0.12, -0.05);
  s.hi = Eigen::Vector3d(0.15, 0.12, 0.2);
  s.resolution = 0.01;
  s.has_plane = true;
  const DepthField f = build_depth_field({top_view()}, s);
  const Eigen::Vector3i dims = f.obstacles->dims();
  const std::vector<float>& values = f.obstacles->values();
  std::vector<Eigen::Vector3i> occupied, free;
  for (long i = 0; i < dims.prod(); ++i) {
    const Eigen::Vector3i p(i % dims.x(), (i / dims.x()) % dims.y(), i / (long(dims.x()) * dims.y()));
    (values[i] < 0 ? occupied : free).push_back(p);
  }
  ASSERT_EQ(static_cast<int>(occupied.size()), f.occupied);
  ASSERT_GT(f.occupied, 100);
  auto nearest = [](const Eigen::Vector3i& p, const std::vector<Eigen::Vector3i>& set) {
    double best = 1e30;
    for (const auto& q : set) best = std::min(best, (q - p).cast<double>().squaredNorm());
    return std::sqrt(best);
  };
  for (long i = 0; i < dims.prod(); ++i) {
    const Eigen::Vector3i p(i % dims.x(), (i / dims.x()) % dims.y(), i / (long(dims.x()) * dims.y()));
    const double want = values[i] < 0 ? -(nearest(p, free) * s.resolution - 0.5 * s.resolution)
                                      : std::min(nearest(p, occupied) * s.resolution - 0.5 * s.resolution, 1.0);
    ASSERT_NEAR(values[i], want, 1e-6) << "node " << p.transpose();
  }
}

TEST(DepthField, RefusesBadInput) {
  DepthFieldSettings s;
  DepthView v = top_view();
  v.camera_pose.R(0, 0) = 2.0;
  EXPECT_THROW(build_depth_field({v}, s), std::invalid_argument);
  v = top_view();
  v.target = PixelMask::Zero(3, 3);
  EXPECT_THROW(build_depth_field({v}, s), std::invalid_argument);
  v = top_view();
  v.K(0, 0) = -1;
  EXPECT_THROW(build_depth_field({v}, s), std::invalid_argument);
  EXPECT_THROW(build_depth_field({}, s), std::invalid_argument);
  s.resolution = 0;
  EXPECT_THROW(build_depth_field({top_view()}, s), std::invalid_argument);
}

}  // namespace
}  // namespace pickplan
