// MergedSdf lookups: the CHOMP hot path (const, reentrant, no allocation).
#include "pickplan/geometry/sdf_merged.hpp"

#include <thread>

namespace pickplan::geometry {

std::int32_t MergedSdf::fill_cell(long cell) const {
  std::int32_t expected = kPending;
  if (state_[cell].compare_exchange_strong(expected, kFilling, std::memory_order_acquire)) {
    const long cx = cell % cells_.x(), cy = cell / cells_.x() % cells_.y(),
               cz = cell / (static_cast<long>(cells_.x()) * cells_.y());
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

double MergedSdf::lower_bound_outside(const double* x) const {
  // Off the covered box every object is beyond the cutoff, and farther by the gap to the box.
  double gap2 = 0;
  for (int a = 0; a < 3; ++a) {
    const double lo = origin_[a], hi = box_hi_[a];
    const double g = x[a] < lo ? lo - x[a] : (x[a] > hi ? x[a] - hi : 0.0);
    gap2 += g * g;
  }
  if (gap2 > 0) return settings_.cutoff + std::sqrt(gap2);
  // On a face (within rounding of the inside test) or NaN: by cells, clamped.
  const double edge = settings_.brick * settings_.resolution;
  const Eigen::Vector3d f((x[0] - origin_.x()) / edge, (x[1] - origin_.y()) / edge, (x[2] - origin_.z()) / edge);
  const Eigen::Vector3d cf = f.cwiseMax(0.0).cwiseMin(cells_.cast<double>() - Eigen::Vector3d::Constant(1e-9));
  if (cf != f) {
    // Outside the covered box every object is beyond the cutoff, and farther by the gap.
    return settings_.cutoff + (f - cf).norm() * edge;
  }
  const long cell =
      (static_cast<long>(cf.z()) * cells_.y() + static_cast<long>(cf.y())) * cells_.x() + static_cast<long>(cf.x());
  return cell_lower_[cell];
}

}  // namespace pickplan::geometry
