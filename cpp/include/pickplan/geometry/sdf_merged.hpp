#pragma once
// A world-frame, sparse "bricked" resampling of the minimum over a scene's posed object grids,
// clamped at a cutoff (the CHOMP padding). One trilinear lookup replaces a lookup per nearby
// object, and points in empty bricks cost one array read: this is what makes the per-iteration
// obstacle cost and the goal-cost estimates cheap.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include <Eigen/Core>

namespace pickplan {

struct MergedSdfSettings {
  double resolution = 0.01;   // node spacing (m): resampling 5 mm object grids is < 1 mm off outside thin walls
  double cutoff = 0.2;        // values are clamped here; queries with a larger cutoff fall back
  int brick = 4;              // voxels per brick edge (a brick stores (brick+1)^3 nodes)
};

class MergedSdf {
 public:
  // `near(center, radius, ids)` writes the ids of the objects that may come within the cutoff of
  // the ball and returns their count; `object_distance(id, x)` is that object's distance at a
  // world point; `lower_bound(center, radius)` bounds every object's distance over the ball.
  template <class NearFn, class ObjectDistanceFn, class LowerBoundFn>
  static MergedSdf build(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const MergedSdfSettings& settings,
                         std::uint64_t exclude_mask, NearFn&& near, ObjectDistanceFn&& object_distance,
                         LowerBoundFn&& lower_bound);

  // Trilinear value (clamped at cutoff) and its exact gradient; `cutoff` with a zero gradient
  // in empty bricks and outside the covered box.
  double distance(const double* x, double* gradient) const;
  // A lower bound of the object distance (unclamped, so it may exceed the cutoff) that holds
  // for the merged interpolant at x and for the exact distance alike.
  double lower_bound(const double* x) const;

  std::uint64_t exclude_mask() const { return exclude_mask_; }
  double cutoff() const { return settings_.cutoff; }
  const MergedSdfSettings& settings() const { return settings_; }
  long num_bricks() const { return static_cast<long>(values_.size() / brick_nodes_); }
  long num_cells() const { return static_cast<long>(brick_of_cell_.size()); }
  std::size_t bytes() const { return values_.size() * sizeof(float) + brick_of_cell_.size() * sizeof(std::int32_t); }
  const Eigen::Vector3d& origin() const { return origin_; }
  const Eigen::Vector3i& cells() const { return cells_; }

 private:
  MergedSdfSettings settings_;
  std::uint64_t exclude_mask_ = 0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  Eigen::Vector3i cells_ = Eigen::Vector3i::Zero();
  double inv_resolution_ = 0.0;
  long brick_nodes_ = 1;
  int brick_shift_ = -1;                     // log2(brick) when a power of two: shifts, not divisions
  double voxels_[3] = {0, 0, 0};             // covered box in voxels (cells * brick)
  std::vector<std::int32_t> brick_of_cell_;  // -1: every node at or beyond the cutoff
  std::vector<float> values_;                // brick after brick, x fastest inside a brick
  std::vector<float> cell_lower_;            // per cell: lower bound of the distance anywhere in it
};

template <class NearFn, class ObjectDistanceFn, class LowerBoundFn>
MergedSdf MergedSdf::build(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const MergedSdfSettings& settings,
                           std::uint64_t exclude_mask, NearFn&& near, ObjectDistanceFn&& object_distance,
                           LowerBoundFn&& lower_bound) {
  MergedSdf m;
  m.settings_ = settings;
  m.exclude_mask_ = exclude_mask;
  m.origin_ = lo;
  m.inv_resolution_ = 1.0 / settings.resolution;
  const int B = settings.brick;
  const double edge = B * settings.resolution;
  for (int a = 0; a < 3; ++a) m.cells_[a] = std::max(1, static_cast<int>(std::ceil((hi[a] - lo[a]) / edge)));
  const long nodes1 = B + 1;
  m.brick_nodes_ = nodes1 * nodes1 * nodes1;
  for (int a = 0; a < 3; ++a) m.voxels_[a] = static_cast<double>(m.cells_[a]) * B;
  for (int shift = 0; shift < 7; ++shift)
    if ((1 << shift) == B) m.brick_shift_ = shift;
  m.brick_of_cell_.assign(static_cast<std::size_t>(m.cells_.prod()), -1);
  m.cell_lower_.assign(m.brick_of_cell_.size(), 0.0f);
  // The cell's half diagonal plus one voxel diagonal: the bound then also holds for the
  // interpolant, whose nodes may lie in the neighbouring cell.
  const double half_diagonal = 0.5 * std::sqrt(3.0) * edge + std::sqrt(3.0) * settings.resolution;
  std::vector<float> brick(m.brick_nodes_);
  int ids[64];
  long cell = 0;
  for (int cz = 0; cz < m.cells_.z(); ++cz)
    for (int cy = 0; cy < m.cells_.y(); ++cy)
      for (int cx = 0; cx < m.cells_.x(); ++cx, ++cell) {
        const Eigen::Vector3d corner = lo + Eigen::Vector3d(cx, cy, cz) * edge;
        const Eigen::Vector3d center = corner.array() + 0.5 * edge;
        const double bound = lower_bound(center, half_diagonal);
        // Rounded down so the float never exceeds the double bound.
        m.cell_lower_[cell] = std::nextafter(static_cast<float>(bound), -std::numeric_limits<float>::infinity());
        if (bound >= settings.cutoff) continue;
        const int n_near = near(center, half_diagonal, ids);
        if (n_near == 0) continue;
        bool any_inside = false;
        long k = 0;
        for (int z = 0; z <= B; ++z)
          for (int y = 0; y <= B; ++y)
            for (int x = 0; x <= B; ++x, ++k) {
              const Eigen::Vector3d node = corner + Eigen::Vector3d(x, y, z) * settings.resolution;
              double d = settings.cutoff;
              for (int c = 0; c < n_near; ++c) d = std::min(d, object_distance(ids[c], node));
              brick[k] = static_cast<float>(d);
              any_inside |= d < settings.cutoff;
            }
        if (!any_inside) continue;
        m.brick_of_cell_[cell] = static_cast<std::int32_t>(m.values_.size() / m.brick_nodes_);
        m.values_.insert(m.values_.end(), brick.begin(), brick.end());
      }
  m.values_.shrink_to_fit();
  return m;
}

}  // namespace pickplan
