#pragma once
// A world-frame, sparse "bricked" resampling of the minimum over a scene's posed object grids,
// clamped at a cutoff (the CHOMP padding). One trilinear lookup replaces a lookup per nearby
// object, and points in empty bricks cost one array read: this is what makes the per-iteration
// obstacle cost and the goal-cost estimates cheap.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <vector>

#include <Eigen/Core>

namespace pickplan::geometry {

struct MergedSdfSettings {
  double resolution = 0.01;  // node spacing (m): resampling 5 mm object grids is < 1 mm off outside thin walls
  double cutoff = 0.2;       // values are clamped here; queries with a larger cutoff fall back
  int brick = 4;             // voxels per brick edge (a brick stores (brick+1)^3 nodes)
};

class MergedSdf {
 public:
  // `fill(corner, center, radius, out)` writes the (brick+1)^3 node values (clamped at the cutoff,
  // x fastest) of the brick whose lowest node is `corner` and returns whether any is below the
  // cutoff; `lower_bound(center, radius)` bounds every object's distance over the ball.
  using BrickFill =
      std::function<bool(const Eigen::Vector3d& corner, const Eigen::Vector3d& center, double radius, float* out)>;
  // Bricks are filled lazily, on the first lookup that lands in them (the same values, computed
  // the same way, as filling them all here): a new scene pays only for the bricks its plans touch.
  template <class LowerBoundFn>
  static MergedSdf build(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const MergedSdfSettings& settings,
                         std::uint64_t exclude_mask, BrickFill fill, LowerBoundFn&& lower_bound);

  // Trilinear value (clamped at cutoff) and its exact gradient; `cutoff` with a zero gradient
  // in empty bricks and outside the covered box. Reentrant: concurrent lookups may fill bricks.
  double distance(const double* x, double* gradient) const;  // inline below: the per-point hot path
  // A lower bound of the object distance (unclamped, so it may exceed the cutoff) that holds
  // for the merged interpolant at x and for the exact distance alike. Inline: the links' culling
  // test calls it per link and waypoint. (A point within rounding of a cell face may read either
  // cell's bound: both bound it, as each covers its cell grown by more than a voxel diagonal.)
  double lower_bound(const double* x) const {
    const double fx = (x[0] - origin_.x()) * inv_edge_, fy = (x[1] - origin_.y()) * inv_edge_,
                 fz = (x[2] - origin_.z()) * inv_edge_;
    if (fx >= 0 && fy >= 0 && fz >= 0 && fx < cells_d_[0] && fy < cells_d_[1] && fz < cells_d_[2]) {
      const long cell =
          (static_cast<long>(fz) * cells_.y() + static_cast<long>(fy)) * cells_.x() + static_cast<long>(fx);
      return cell_lower_[cell];
    }
    return lower_bound_outside(x);
  }

  std::uint64_t exclude_mask() const { return exclude_mask_; }
  double cutoff() const { return settings_.cutoff; }
  const MergedSdfSettings& settings() const { return settings_; }
  long num_bricks() const { return num_slots_; }  // cells that may hold a brick (filled or not yet)
  long num_filled() const;                        // bricks filled so far with a value below the cutoff
  long num_cells() const { return num_cells_; }
  std::size_t bytes() const {
    return num_slots_ * brick_nodes_ * sizeof(float) + num_cells_ * (2 * sizeof(std::int32_t) + sizeof(float));
  }
  const Eigen::Vector3d& origin() const { return origin_; }
  const Eigen::Vector3i& cells() const { return cells_; }

 private:
  // Per-cell state: a filled brick's slot (>= 0) or one of these.
  static constexpr std::int32_t kEmpty = -1, kPending = -2, kFilling = -3;
  std::int32_t fill_cell(long cell) const;            // the cell's final state, filling its brick if pending
  double lower_bound_outside(const double* x) const;  // lower_bound off the covered box (or NaN)

  MergedSdfSettings settings_;
  std::uint64_t exclude_mask_ = 0;
  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();
  Eigen::Vector3i cells_ = Eigen::Vector3i::Zero();
  double inv_resolution_ = 0.0;
  double inv_edge_ = 0.0;                             // 1 / (brick * resolution)
  double cells_d_[3] = {0, 0, 0};                     // cells_ as doubles
  Eigen::Vector3d box_hi_ = Eigen::Vector3d::Zero();  // the covered box's upper corner
  long brick_nodes_ = 1;
  long num_cells_ = 0, num_slots_ = 0;
  int brick_shift_ = -1;                                // log2(brick) when a power of two: shifts, not divisions
  double voxels_[3] = {0, 0, 0};                        // covered box in voxels (cells * brick)
  std::unique_ptr<std::atomic<std::int32_t>[]> state_;  // per cell
  std::unique_ptr<std::int32_t[]> slot_;                // per cell: its reserved brick slot (-1: beyond the cutoff)
  std::unique_ptr<float[]> values_;      // slot after slot, x fastest inside a brick; written once per slot
  std::unique_ptr<float[]> cell_lower_;  // per cell: lower bound of the distance anywhere in it
  BrickFill fill_;
  double half_diagonal_ = 0;
};

template <class LowerBoundFn>
MergedSdf MergedSdf::build(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, const MergedSdfSettings& settings,
                           std::uint64_t exclude_mask, BrickFill fill, LowerBoundFn&& lower_bound) {
  MergedSdf m;
  m.settings_ = settings;
  m.exclude_mask_ = exclude_mask;
  m.origin_ = lo;
  m.inv_resolution_ = 1.0 / settings.resolution;
  m.fill_ = std::move(fill);
  const int B = settings.brick;
  const double edge = B * settings.resolution;
  for (int a = 0; a < 3; ++a) m.cells_[a] = std::max(1, static_cast<int>(std::ceil((hi[a] - lo[a]) / edge)));
  const long nodes1 = B + 1;
  m.brick_nodes_ = nodes1 * nodes1 * nodes1;
  for (int a = 0; a < 3; ++a) m.voxels_[a] = static_cast<double>(m.cells_[a]) * B;
  for (int a = 0; a < 3; ++a) m.cells_d_[a] = static_cast<double>(m.cells_[a]);
  m.inv_edge_ = 1.0 / edge;
  m.box_hi_ = lo + m.cells_.cast<double>() * edge;
  for (int shift = 0; shift < 7; ++shift)
    if ((1 << shift) == B) m.brick_shift_ = shift;
  m.num_cells_ = static_cast<long>(m.cells_.prod());
  m.state_.reset(new std::atomic<std::int32_t>[m.num_cells_]);
  m.slot_.reset(new std::int32_t[m.num_cells_]);
  m.cell_lower_.reset(new float[m.num_cells_]);
  // The cell's half diagonal plus one voxel diagonal: the bound then also holds for the
  // interpolant, whose nodes may lie in the neighbouring cell.
  m.half_diagonal_ = 0.5 * std::sqrt(3.0) * edge + std::sqrt(3.0) * settings.resolution;
  long cell = 0;
  for (int cz = 0; cz < m.cells_.z(); ++cz)
    for (int cy = 0; cy < m.cells_.y(); ++cy)
      for (int cx = 0; cx < m.cells_.x(); ++cx, ++cell) {
        const Eigen::Vector3d corner = lo + Eigen::Vector3d(cx, cy, cz) * edge;
        const Eigen::Vector3d center = corner.array() + 0.5 * edge;
        const double bound = lower_bound(center, m.half_diagonal_);
        // Rounded down so the float never exceeds the double bound.
        m.cell_lower_[cell] = std::nextafter(static_cast<float>(bound), -std::numeric_limits<float>::infinity());
        const bool candidate = bound < settings.cutoff;
        m.slot_[cell] = candidate ? static_cast<std::int32_t>(m.num_slots_++) : -1;
        m.state_[cell].store(candidate ? kPending : kEmpty, std::memory_order_relaxed);
      }
  // Uninitialized: the pages of bricks never filled are never touched.
  m.values_.reset(new float[static_cast<std::size_t>(std::max(1L, m.num_slots_ * m.brick_nodes_))]);
  return m;
}

inline double MergedSdf::distance(const double* x, double* gradient) const {
  const int B = settings_.brick;
  const double fx = (x[0] - origin_.x()) * inv_resolution_, fy = (x[1] - origin_.y()) * inv_resolution_,
               fz = (x[2] - origin_.z()) * inv_resolution_;
  const auto empty = [&] {
    if (gradient) gradient[0] = gradient[1] = gradient[2] = 0.0;
    return settings_.cutoff;
  };
  // Negated comparisons also reject NaN; the upper bounds keep the int conversions in range.
  if (!(fx >= 0 && fy >= 0 && fz >= 0 && fx < voxels_[0] && fy < voxels_[1] && fz < voxels_[2])) return empty();
  const int ix = static_cast<int>(fx), iy = static_cast<int>(fy), iz = static_cast<int>(fz);
  // The default brick (4) is a power of two: a shift instead of three integer divisions.
  const int cx = brick_shift_ >= 0 ? ix >> brick_shift_ : ix / B, cy = brick_shift_ >= 0 ? iy >> brick_shift_ : iy / B,
            cz = brick_shift_ >= 0 ? iz >> brick_shift_ : iz / B;
  const long cell = (static_cast<long>(cz) * cells_.y() + cy) * cells_.x() + cx;
  std::int32_t brick = state_[cell].load(std::memory_order_acquire);
  if (brick < 0) {
    if (brick == kEmpty) return empty();
    brick = fill_cell(cell);
    if (brick < 0) return empty();
  }
  // Local voxel inside the brick; the brick's last node layer is shared with its neighbour.
  const int i = ix - cx * B, j = iy - cy * B, k = iz - cz * B;
  const double tx = fx - ix, ty = fy - iy, tz = fz - iz;
  const long sy = B + 1, sz = sy * sy;
  const float* c = values_.get() + brick * brick_nodes_ + (k * sz + j * sy + i);
  const double c000 = c[0], c100 = c[1], c010 = c[sy], c110 = c[1 + sy];
  const double c001 = c[sz], c101 = c[1 + sz], c011 = c[sy + sz], c111 = c[1 + sy + sz];
  const double c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
  const double c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
  const double c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  const double d = c0 + tz * (c1 - c0);
  if (d >= settings_.cutoff) return empty();
  if (gradient) {
    gradient[0] = ((1 - tz) * ((1 - ty) * (c100 - c000) + ty * (c110 - c010)) +
                   tz * ((1 - ty) * (c101 - c001) + ty * (c111 - c011))) *
                  inv_resolution_;
    gradient[1] = ((1 - tz) * (c10 - c00) + tz * (c11 - c01)) * inv_resolution_;
    gradient[2] = (c1 - c0) * inv_resolution_;
  }
  return d;
}

}  // namespace pickplan::geometry
