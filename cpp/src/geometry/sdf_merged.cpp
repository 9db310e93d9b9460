// MergedSdf lookups: the CHOMP hot path (const, reentrant, no allocation).
#include "pickplan/geometry/sdf_merged.hpp"

#include <thread>

namespace pickplan {

double MergedSdf::distance(const double* x, double* gradient) const {
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
                   tz * ((1 - ty) * (c101 - c001) + ty * (c111 - c011))) * inv_resolution_;
    gradient[1] = ((1 - tz) * (c10 - c00) + tz * (c11 - c01)) * inv_resolution_;
    gradient[2] = (c1 - c0) * inv_resolution_;
  }
  return d;
}

std::int32_t MergedSdf::fill_cell(long cell) const {
  std::int32_t expected = kPending;
  if (state_[cell].compare_exchange_strong(expected, kFilling, std::memory_order_acquire)) {
    const long cx = cell % cells_.x(), cy = cell / cells_.x() % cells_.y(), cz = cell / (static_cast<long>(cells_.x()) * cells_.y());
    const double edge = settings_.brick * settings_.resolution;
    const Eigen::Vector3d corner = origin_ + Eigen::Vector3d(cx, cy, cz) * edge;
    const Eigen::Vector3d center = corner.array() + 0.5 * edge;
    const std::int32_t slot = slot_[cell];
    const bool filled = fill_(corner, center, half_diagonal_, values_.get() + slot * brick_nodes_);
    const std::int32_t state = filled ? slot : kEmpty;
    state_[cell].store(state, std::memory_order_release);
    return state;
  }
  // Another thread is filling this brick: wait for it (microseconds).
  while (expected == kFilling) {
    std::this_thread::yield();
    expected = state_[cell].load(std::memory_order_acquire);
  }
  return expected;
}

long MergedSdf::num_filled() const {
  long n = 0;
  for (long c = 0; c < num_cells_; ++c) n += state_[c].load(std::memory_order_relaxed) >= 0;
  return n;
}

double MergedSdf::lower_bound(const double* x) const {
  const double edge = settings_.brick * settings_.resolution;
  const Eigen::Vector3d f((x[0] - origin_.x()) / edge, (x[1] - origin_.y()) / edge, (x[2] - origin_.z()) / edge);
  const Eigen::Vector3d cf = f.cwiseMax(0.0).cwiseMin(cells_.cast<double>() - Eigen::Vector3d::Constant(1e-9));
  if (cf != f) {
    // Outside the covered box every object is beyond the cutoff, and farther by the gap.
    return settings_.cutoff + (f - cf).norm() * edge;
  }
  const long cell = (static_cast<long>(cf.z()) * cells_.y() + static_cast<long>(cf.y())) * cells_.x() + static_cast<long>(cf.x());
  return cell_lower_[cell];
}

}  // namespace pickplan
