#pragma once
// Signed distance fields: a dense grid per object mesh (exact distance to the triangles near
// the surface, closest-triangle propagation elsewhere, sign by 3-axis ray-parity vote so small
// holes do not flip it), and a SceneSdf of posed grids and analytic primitives (boxes,
// cylinders, spheres: closed forms, no grid) plus an analytic table box.
#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/transform.hpp"
#include "pickplan/geometry/primitives.hpp"
#include "pickplan/geometry/sdf_merged.hpp"

namespace pickplan::geometry {

using Vertices = Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>;
using Faces = Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>;

struct SdfBuildSettings {
  double resolution = 0.005;  // voxel edge (m)
  double margin = 0.2;        // grid extends this far beyond the mesh bounds (>= CHOMP padding)
};

struct SdfBuildReport {
  int degenerate_faces = 0;        // zero-area triangles skipped
  double sign_disagreement = 0.0;  // fraction of nodes where the three ray axes disagreed (holes)
};

class SdfGrid {
 public:
  SdfGrid() = default;
  // Throws std::invalid_argument for empty or degenerate meshes, bad indices, NaN.
  static SdfGrid build(const Vertices& V, const Faces& F, const SdfBuildSettings& settings = {},
                       SdfBuildReport* report = nullptr);
  // From stored values (cache): dims (nx, ny, nz), values in x-fastest order.
  static SdfGrid from_values(const Eigen::Vector3d& origin, double resolution, const Eigen::Vector3i& dims,
                             std::vector<float> values);

  // Trilinear value and its exact gradient at a point in the grid frame. Outside the grid the
  // value continues as value(clamped) + distance to the grid box, gradient pointing outward.
  double distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient = nullptr) const;

  const Eigen::Vector3d& origin() const { return origin_; }
  double resolution() const { return resolution_; }
  const Eigen::Vector3i& dims() const { return dims_; }
  Eigen::Vector3d upper() const { return origin_ + (dims_.cast<double>() - Eigen::Vector3d::Ones()) * resolution_; }
  const std::vector<float>& values() const { return values_; }
  // Box around the surface (nodes within one voxel of it, padded by a voxel): every point
  // farther than c from this box is farther than c from the mesh. Used for cheap rejection.
  const Eigen::Vector3d& surface_lo() const { return surface_lo_; }
  const Eigen::Vector3d& surface_hi() const { return surface_hi_; }

 private:
  void compute_surface_box();
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  double resolution_ = 0.0;
  Eigen::Vector3i dims_ = Eigen::Vector3i::Zero();
  std::vector<float> values_;
  Eigen::Vector3d surface_lo_ = Eigen::Vector3d::Zero(), surface_hi_ = Eigen::Vector3d::Zero();
};

struct SdfQuery {
  double distance;
  Eigen::Vector3d gradient;
};

// Posed grids plus an axis-aligned (in its own pose) table box. Immutable after construction;
// queries are const and reentrant.
class SceneSdf {
 public:
  struct Body {
    std::shared_ptr<const SdfGrid> grid;  // null for an analytic primitive
    Primitive primitive;                  // used when grid is null
    core::Transform pose;                 // grid (primitive) frame in the world
    core::Transform inverse;              // world into grid frame
    Eigen::Vector3d lo, hi;               // surface box (see SdfGrid::surface_lo) in the grid frame
    double slack = 0;                     // how far the interpolated value may sit below the true distance
    // Signed distance at a point in the body's frame (gradient in that frame).
    double local_distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient = nullptr) const {
      return grid ? grid->distance(p, gradient) : primitive.signed_distance(p, gradient);
    }
  };

  SceneSdf() = default;
  // Adds an object; returns its index (used by exclusion masks; at most 64 objects).
  int add_object(std::shared_ptr<const SdfGrid> grid, const core::Transform& pose);
  // Adds a solid primitive, queried in closed form; same index space and limits as add_object.
  int add_primitive(const Primitive& primitive, const core::Transform& pose);
  void set_table(const Eigen::Vector3d& size, const core::Transform& pose);
  // Moves object `index` (an object that moves: replanning). A moved object becomes live: it is
  // left out of every merged grid from then on and queried on its own grid beside them, so moving
  // it again costs nothing. A merged grid that held it gives way to one for the same mask without
  // it (kept if the scene has it already, e.g. the grid without the target; merged anew otherwise,
  // its bricks filled on first lookup).
  void set_pose(int index, const core::Transform& pose);
  // The objects moved by set_pose (bit i: object i).
  std::uint64_t live_mask() const { return live_; }
  void clear_table() { has_table_ = false; }

  // Resamples the minimum over the objects not in `exclude_mask` into one world-frame bricked
  // grid (see MergedSdf). Afterwards, queries with that object mask and a cutoff no larger than
  // settings.cutoff take one lookup (plus the analytic table); others use the per-object path.
  // A scene keeps one merged grid per object mask (at most kMaxMerged; merging a mask again
  // replaces its grid): e.g. the target left out (grasping) and the target in (the transit).
  // Live objects (set_pose) are never merged: a query's live objects are added to its grid's answer.
  // Adding an object drops the merged grids. Throws std::invalid_argument on bad settings.
  void merge(std::uint64_t exclude_mask, const MergedSdfSettings& settings = {});
  static constexpr int kMaxMerged = 4;
  // The first grid merged (nullptr if none), or the one for an object mask (table bit ignored).
  const MergedSdf* merged() const { return merged_.empty() ? nullptr : merged_.front().get(); }
  const MergedSdf* merged(std::uint64_t exclude_mask) const {
    for (const auto& m : merged_)
      if (((exclude_mask | live_) & ~kTableBit) == m->exclude_mask()) return m.get();
    return nullptr;
  }
  int num_merged() const { return static_cast<int>(merged_.size()); }
  std::vector<std::uint64_t> merged_masks() const {
    std::vector<std::uint64_t> out;
    for (const auto& m : merged_) out.push_back(m->exclude_mask());
    return out;
  }

  int num_objects() const { return static_cast<int>(bodies_.size()); }
  bool has_table() const { return has_table_; }

  // Signed distance to the nearest non-excluded body (bit i of exclude_mask excludes object i;
  // bit 63 excludes the table). Bodies whose grid box lies farther than `cutoff` are skipped:
  // when everything is beyond it the result is `cutoff` with a zero gradient.
  double distance(const Eigen::Vector3d& x, Eigen::Vector3d* gradient, double cutoff,
                  std::uint64_t exclude_mask = 0) const;
  // A lower bound of distance(x, ., inf, exclude_mask) that is cheap (one array read with a
  // matching merged grid, a box gap per object otherwise); used to cull whole links.
  double lower_bound(const Eigen::Vector3d& x, std::uint64_t exclude_mask = 0) const;
  // The same bound for the objects and for the table apart (+inf for an absent or excluded
  // part), so a caller can skip either part for a whole link (both sides 1-Lipschitz).
  struct PartBounds {
    double objects, table;
  };
  PartBounds part_lower_bounds(const Eigen::Vector3d& x, std::uint64_t exclude_mask = 0) const;
  // The same, by the per-object grids only (never the merged grid): the reference.
  double distance_unmerged(const Eigen::Vector3d& x, Eigen::Vector3d* gradient, double cutoff,
                           std::uint64_t exclude_mask = 0) const;
  // Batched: N points (row-major N x 3) into dist (N) and grad (N x 3, may be null).
  void distances(const double* points, long n, double* dist, double* grad, double cutoff,
                 std::uint64_t exclude_mask = 0) const {
    distances(points, n, dist, grad, cutoff, exclude_mask, true, true);
  }
  // Restricted to the objects and/or the table (callers that know a part is beyond the cutoff).
  void distances(const double* points, long n, double* dist, double* grad, double cutoff, std::uint64_t exclude_mask,
                 bool objects, bool table) const;

  static constexpr std::uint64_t kTableBit = std::uint64_t{1} << 63;

 private:
  double table_distance(const Eigen::Vector3d& x, Eigen::Vector3d* gradient) const;
  // The merged grid (objects) and optionally the table, for a query use_merged() accepts
  // (inline: it is the per-point body of the batched hot loop).
  double merged_distance(const MergedSdf& merged, const double* x, double* gradient, double cutoff, bool table,
                         std::uint64_t live) const;
  // The live objects (bits of `live`) where nearer than `best`: the nearer distance and its gradient.
  double live_distance(const double* x, double* gradient, double best, std::uint64_t live) const;
  std::uint64_t live_included(std::uint64_t exclude_mask) const { return live_ & ~exclude_mask & ~kTableBit; }
  // The merged grid that answers this query exactly as built (nullptr: the per-object path).
  const MergedSdf* use_merged(std::uint64_t exclude_mask, double cutoff) const {
    const MergedSdf* m = merged(exclude_mask);
    return m && cutoff <= m->cutoff() ? m : nullptr;
  }

  std::vector<Body> bodies_;
  std::vector<std::shared_ptr<const MergedSdf>> merged_;
  std::uint64_t live_ = 0;
  bool has_table_ = false;
  bool table_axis_aligned_ = false;
  Eigen::Vector3d table_half_ = Eigen::Vector3d::Zero();
  core::Transform table_pose_, table_inverse_;
};

inline double SceneSdf::merged_distance(const MergedSdf& merged, const double* x, double* gradient, double cutoff,
                                        bool table, std::uint64_t live) const {
  double g[3];
  double best = merged.distance(x, gradient ? g : nullptr);
  if (best >= cutoff) {
    best = cutoff;
    g[0] = g[1] = g[2] = 0.0;
  }
  if (live) best = live_distance(x, gradient ? g : nullptr, best, live);
  if (table) {
    Eigen::Vector3d gt;
    const double d = table_distance(Eigen::Map<const Eigen::Vector3d>(x), gradient ? &gt : nullptr);
    if (d < best) {
      best = d;
      g[0] = gt.x(), g[1] = gt.y(), g[2] = gt.z();
    }
  }
  if (gradient) gradient[0] = g[0], gradient[1] = g[1], gradient[2] = g[2];
  return best;
}

// Exact signed distance to a box of half extents h centred at the origin, with gradient.
double box_signed_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& h, Eigen::Vector3d* gradient);

}  // namespace pickplan::geometry
