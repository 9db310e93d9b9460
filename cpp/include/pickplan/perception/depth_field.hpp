#pragma once
// A world model from depth images: the views are fused by space carving into obstacle / target /
// free voxels over a workspace box, and an exact Euclidean distance transform of the obstacle voxels
// gives a signed distance grid the planner queries like an object's SDF (SdfGrid).
//
// Each voxel centre is projected into every view. In a view where it lands on a pixel with a depth
// d, it is FREE when it lies in front of the measured surface by more than `surface_margin`, TARGET
// when the pixel belongs to the target and it lies at or behind the surface, OCCUPIED otherwise. Over
// the views: FREE if any view sees it free (a camera looked through it); else TARGET if a view saw
// the target there; else OCCUPIED if a view saw it behind a surface (space no camera has seen
// behind a surface counts as occupied); else (never in a view with a depth) FREE. Voxels below the
// support plane (+ `plane_margin`) are left to the analytic table.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/transform.hpp"
#include "pickplan/geometry/sdf.hpp"

namespace pickplan::perception {

using DepthImage = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using PixelMask = Eigen::Matrix<std::uint8_t, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct DepthView {
  DepthImage depth;             // H x W metres along the optical axis; <= 0 or non-finite: no return
  Eigen::Matrix3d K;            // pinhole intrinsics (fx, fy, cx, cy; pixel centres at integer + 0.5)
  core::Transform camera_pose;  // camera -> world, OpenCV axes: z forward, x right, y down
  PixelMask target;             // H x W, nonzero on the target (may be empty: no target in this view)
};

struct DepthFieldSettings {
  Eigen::Vector3d lo = Eigen::Vector3d(-0.1, -0.6, -0.02);  // workspace box (world)
  Eigen::Vector3d hi = Eigen::Vector3d(1.0, 0.6, 0.6);
  double resolution = 0.01;       // voxel edge (m)
  double surface_margin = 0.003;  // m in front of a measured depth still counted at the surface (depth noise)
  bool has_plane = false;         // support plane n . x = d (n up): voxels below it are the table's
  Eigen::Vector3d plane_normal = Eigen::Vector3d::UnitZ();
  double plane_offset = 0.0;
  double plane_margin = 0.01;  // m above the plane still counted as the table
  int target_stride = 1;       // keep every k-th target pixel (both axes) as a target point
  void validate() const;       // throws std::invalid_argument
};

struct DepthField {
  std::shared_ptr<const geometry::SdfGrid> obstacles;  // signed distance to OCCUPIED voxels (world frame grid)
  geometry::Vertices target_points, target_normals;    // observed target surface, normals towards the camera side
  int occupied = 0, target = 0, free = 0;              // voxel counts
};

// Throws std::invalid_argument for mismatched sizes, non-rigid poses, bad intrinsics or settings.
DepthField build_depth_field(const std::vector<DepthView>& views, const DepthFieldSettings& settings);

// The first of the plane hypotheses normals.row(k) . x = offsets(k) with the most of `points` within
// `tolerance` (the support plane's RANSAC; python/pickplan/perception/field.py draws the hypotheses),
// and its inlier count; index -1 without hypotheses. A hypothesis is left as soon as the points it
// has not counted could not lift it above the best so far.
struct PlaneChoice {
  long index = -1;
  long inliers = 0;
};
PlaneChoice most_inliers(const geometry::Vertices& points, const geometry::Vertices& normals,
                         const Eigen::VectorXd& offsets, double tolerance);

// Distance from every node of the grid (origin, resolution, dims; x fastest) to the nearest of
// `points` (exact, by a k-d tree): the observed target's unsigned distance grid.
std::vector<float> point_distance_grid(const geometry::Vertices& points, const Eigen::Vector3d& origin,
                                       double resolution, const Eigen::Vector3i& dims);

// Exact squared Euclidean distance transform (Felzenszwalb and Huttenlocher) of a binary grid,
// x-fastest dims: for each voxel the squared distance (in voxels) to the nearest `true` voxel
// (a large value where there is none).
std::vector<float> squared_distance_transform(const std::vector<std::uint8_t>& mask, const Eigen::Vector3i& dims);

}  // namespace pickplan::perception
