// Radius pairs (grasps from points' patches and antipodal partners) against brute force, and the
// clearance of sample points in many frames against closed-form distances to primitives.
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <random>

#include "pickplan/geometry/frame_clearance.hpp"
#include "pickplan/geometry/primitives.hpp"
#include "pickplan/omg/point_queries.hpp"
#include "pickplan/perception/depth_field.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::perception;
using namespace pickplan::omg;

namespace pickplan {
namespace {

RowMatrixXd random_points(int n, double spread, unsigned seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> g(0.0, spread);
  RowMatrixXd P(n, 3);
  for (int i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) P(i, a) = g(rng);
  return P;
}

TEST(RadiusPairs, EqualBruteForceInQueryOrderAscending) {
  const RowMatrixXd P = random_points(700, 0.05, 3);
  std::vector<long> queries = {5, 0, 699, 350, 5, 123};  // any order, repeats kept
  std::vector<std::uint8_t> keep(700);
  for (int k = 0; k < 700; ++k) keep[k] = (k % 3) != 0;
  for (double radius : {0.004, 0.02, 0.08}) {
    for (bool masked : {false, true}) {
      const RadiusPairs got = radius_pairs(P, queries, radius, masked ? keep : std::vector<std::uint8_t>{});
      std::vector<long> ei, ej;
      for (long i : queries)
        for (long j = 0; j < P.rows(); ++j)
          if ((!masked || keep[j]) && (P.row(j) - P.row(i)).squaredNorm() <= radius * radius)
            ei.push_back(i), ej.push_back(j);
      EXPECT_EQ(got.i, ei) << "radius " << radius;
      EXPECT_EQ(got.j, ej) << "radius " << radius;
    }
  }
}

TEST(RadiusPairs, InTheGivenOrder) {
  const RowMatrixXd P = random_points(300, 0.05, 5);
  std::vector<long> order(300);
  for (long k = 0; k < 300; ++k) order[k] = (k * 7 + 3) % 300;  // a permutation (7 and 300 coprime)
  const std::vector<long> queries = {0, 299, 17};
  for (double radius : {0.01, 0.2}) {  // few found (sorted) and nearly all (marked)
    const RadiusPairs got = radius_pairs(P, queries, radius, {}, order);
    std::vector<long> ej;
    for (long i : queries)
      for (long j : order)
        if ((P.row(j) - P.row(i)).squaredNorm() <= radius * radius) ej.push_back(j);
    EXPECT_EQ(got.j, ej) << "radius " << radius;
  }
  EXPECT_THROW(radius_pairs(P, queries, 0.1, {}, std::vector<long>(300, 0)), std::invalid_argument);
}

TEST(RadiusPairs, EveryPointItsOwnNeighbourAndBadInputRefused) {
  const RowMatrixXd P = random_points(50, 1.0, 4);  // far apart at this radius: alone
  std::vector<long> all(50);
  for (long k = 0; k < 50; ++k) all[k] = k;
  const RadiusPairs got = radius_pairs(P, all, 1e-6);
  EXPECT_EQ(got.i, all);
  EXPECT_EQ(got.j, all);
  EXPECT_THROW(radius_pairs(P, {50}, 0.1), std::invalid_argument);
  EXPECT_THROW(radius_pairs(P, {0}, 0.0), std::invalid_argument);
  EXPECT_THROW(radius_pairs(P, {0}, 0.1, std::vector<std::uint8_t>(3, 1)), std::invalid_argument);
}

TEST(FrameClearance, EqualsClosedFormDistancesInEveryFrame) {
  SceneSdf scene;
  const Primitive ball = Primitive::sphere(0.05), block = Primitive::box({0.1, 0.04, 0.06});
  Transform T_block;
  T_block.p = Eigen::Vector3d(0.12, 0.0, 0.0);
  scene.add_primitive(ball, Transform{});
  scene.add_primitive(block, T_block);
  const RowMatrixXd P = random_points(6, 0.05, 7);  // few points: some frames keep all of them clear
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-0.1, 0.1);
  const int K = 200;
  FrameMatrix F(K, 16);
  std::vector<Transform> poses(K);
  for (int k = 0; k < K; ++k) {
    const Eigen::Quaterniond q = Eigen::Quaterniond(Eigen::Vector4d(u(rng), u(rng), u(rng), u(rng))).normalized();
    poses[k].R = q.toRotationMatrix();
    poses[k].p = 1.5 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    Eigen::Matrix<double, 4, 4, Eigen::RowMajor> M = Eigen::Matrix<double, 4, 4, Eigen::RowMajor>::Identity();
    M.topLeftCorner<3, 3>() = poses[k].R;
    M.topRightCorner<3, 1>() = poses[k].p;
    F.row(k) = Eigen::Map<const Eigen::Matrix<double, 1, 16>>(M.data());
  }
  for (bool inverse : {true, false})
    for (std::uint64_t mask : {std::uint64_t{0}, std::uint64_t{2}}) {
      FrameClearance s;
      s.inverse = inverse, s.reach = 0.12, s.threshold = 0.01, s.cutoff = 0.05, s.exclude_mask = mask;
      const std::vector<std::uint8_t> got = clear_in_frames(F, P, scene, s);
      int clear = 0;
      for (int k = 0; k < K; ++k) {
        bool expected = true;
        for (long n = 0; n < P.rows(); ++n) {
          const Eigen::Vector3d p = P.row(n).transpose();
          const Eigen::Vector3d x = inverse ? poses[k].inverse().apply(p) : poses[k].apply(p);
          if (inverse && x.squaredNorm() >= s.reach * s.reach) continue;
          double d = std::min(s.cutoff, ball.signed_distance(x));
          if (!(mask & 2)) d = std::min(d, block.signed_distance(T_block.inverse().apply(x)));
          expected = expected && d > s.threshold;
        }
        EXPECT_EQ(got[k] != 0, expected) << "frame " << k << " inverse " << inverse << " mask " << mask;
        clear += expected;
      }
      EXPECT_GT(clear, 0);  // both verdicts occur
      EXPECT_LT(clear, K);
    }
}

TEST(PointDistanceGrid, EveryNodeTheBruteForceNearestDistance) {
  const RowMatrixXd P = random_points(400, 0.03, 9);
  const Vertices V = P;
  const Eigen::Vector3d origin(-0.08, -0.07, -0.09);
  const double res = 0.006;
  const Eigen::Vector3i dims(27, 25, 30);
  const std::vector<float> got = point_distance_grid(V, origin, res, dims);
  long k = 0;
  for (int z = 0; z < dims.z(); ++z)
    for (int y = 0; y < dims.y(); ++y)
      for (int x = 0; x < dims.x(); ++x, ++k) {
        const Eigen::Vector3d q = origin + res * Eigen::Vector3d(x, y, z);
        double best = 1e300;
        for (long i = 0; i < P.rows(); ++i) {
          const double dx = q.x() - P(i, 0), dy = q.y() - P(i, 1), dz = q.z() - P(i, 2);
          best = std::min(best, dx * dx + dy * dy + dz * dz);  // summed as the k-d tree sums
        }
        ASSERT_EQ(got[k], static_cast<float>(std::sqrt(best))) << "node " << x << " " << y << " " << z;
      }
}

}  // namespace
}  // namespace pickplan
