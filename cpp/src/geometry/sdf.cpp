// Queries of SdfGrid and SceneSdf: the hot path of CHOMP (no allocation, const, reentrant).
#include <cmath>
#include <limits>
#include <stdexcept>

#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {

double SdfGrid::distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient) const {
  const Eigen::Vector3d lo = origin_, hi = upper();
  const Eigen::Vector3d pc = p.cwiseMax(lo).cwiseMin(hi);
  const Eigen::Vector3d f = (pc - origin_) / resolution_;
  int i = static_cast<int>(f.x()), j = static_cast<int>(f.y()), k = static_cast<int>(f.z());
  i = std::min(std::max(i, 0), dims_.x() - 2);
  j = std::min(std::max(j, 0), dims_.y() - 2);
  k = std::min(std::max(k, 0), dims_.z() - 2);
  const double tx = f.x() - i, ty = f.y() - j, tz = f.z() - k;
  const long sx = 1, sy = dims_.x(), sz = static_cast<long>(dims_.x()) * dims_.y();
  const float* c = values_.data() + (k * sz + j * sy + i);
  const double c000 = c[0], c100 = c[sx], c010 = c[sy], c110 = c[sx + sy];
  const double c001 = c[sz], c101 = c[sx + sz], c011 = c[sy + sz], c111 = c[sx + sy + sz];
  const double c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
  const double c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
  const double c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
  double d = c0 + tz * (c1 - c0);
  const Eigen::Vector3d out = p - pc;
  const double out_n2 = out.squaredNorm();
  if (gradient) {
    const double dx = (1 - tz) * ((1 - ty) * (c100 - c000) + ty * (c110 - c010)) +
                      tz * ((1 - ty) * (c101 - c001) + ty * (c111 - c011));
    const double dy = (1 - tz) * (c10 - c00) + tz * (c11 - c01);
    const double dz = c1 - c0;
    *gradient = Eigen::Vector3d(dx, dy, dz) / resolution_;
  }
  if (out_n2 > 0) {
    // Exact derivative of value(clamp(p)) + |p - clamp(p)|: clamped axes follow the outward term.
    const double out_n = std::sqrt(out_n2);
    if (gradient) {
      for (int a = 0; a < 3; ++a)
        if (out[a] != 0) (*gradient)[a] = 0;
      *gradient += out / out_n;
    }
    d += out_n;
  }
  return d;
}

double box_signed_distance(const Eigen::Vector3d& p, const Eigen::Vector3d& h, Eigen::Vector3d* gradient) {
  const Eigen::Vector3d q = p.cwiseAbs() - h;
  const Eigen::Vector3d qpos = q.cwiseMax(0.0);
  const double outside = qpos.norm();
  if (outside > 0) {
    if (gradient) {
      *gradient = qpos / outside;
      for (int a = 0; a < 3; ++a)
        if (p[a] < 0) (*gradient)[a] = -(*gradient)[a];
    }
    return outside;
  }
  int axis = 0;
  q.maxCoeff(&axis);
  if (gradient) {
    gradient->setZero();
    (*gradient)[axis] = p[axis] < 0 ? -1.0 : 1.0;
  }
  return q[axis];
}

int SceneSdf::add_object(std::shared_ptr<const SdfGrid> grid, const core::Transform& pose) {
  if (!grid) throw std::invalid_argument("SceneSdf: null grid");
  if (bodies_.size() >= 63) throw std::invalid_argument("SceneSdf: at most 63 objects (exclusion masks are 64-bit)");
  Body b;
  b.grid = std::move(grid);
  b.pose = pose;
  b.inverse = pose.inverse();
  b.lo = b.grid->surface_lo();
  b.hi = b.grid->surface_hi();
  b.slack = b.grid->resolution();
  bodies_.push_back(std::move(b));
  merged_.clear();
  return static_cast<int>(bodies_.size()) - 1;
}

void SceneSdf::set_pose(int index, const core::Transform& pose) {
  if (index < 0 || index >= num_objects())
    throw std::out_of_range("SceneSdf: no object " + std::to_string(index) + " (" + std::to_string(num_objects()) +
                            " objects)");
  core::require_rigid("SceneSdf: object pose", pose.matrix());
  bodies_[index].pose = pose;
  bodies_[index].inverse = pose.inverse();
  const std::uint64_t bit = std::uint64_t{1} << index;
  if (live_ & bit) return;  // in no merged grid: nothing to redo
  live_ |= bit;
  std::vector<std::shared_ptr<const MergedSdf>> kept;
  std::vector<std::pair<std::uint64_t, MergedSdfSettings>> without;
  for (auto& m : merged_) {
    if (m->exclude_mask() & bit)
      kept.push_back(std::move(m));
    else
      without.emplace_back(m->exclude_mask() | bit, m->settings());
  }
  merged_ = std::move(kept);
  for (const auto& [mask, settings] : without)
    if (!merged(mask)) merge(mask, settings);
}

namespace {
// Squared gap from a point in a body's frame to its surface box (0 inside it).
double box_gap2(const SceneSdf::Body& b, const Eigen::Vector3d& xl) {
  return (xl - xl.cwiseMax(b.lo).cwiseMin(b.hi)).squaredNorm();
}
}  // namespace

double SceneSdf::live_distance(const double* x, double* gradient, double best, std::uint64_t live) const {
  const Eigen::Map<const Eigen::Vector3d> p(x);
  Eigen::Vector3d g;
  for (int i = 0; live; ++i, live >>= 1) {
    if (!(live & 1)) continue;
    const Body& b = bodies_[i];
    const Eigen::Vector3d xl = b.inverse.apply(p);
    const double g2 = box_gap2(b, xl);
    if (g2 > 0 && (best <= 0 || g2 >= best * best)) continue;  // its surface box is farther than best
    const double d = b.local_distance(xl, gradient ? &g : nullptr);
    if (d < best) {
      best = d;
      if (gradient) Eigen::Map<Eigen::Vector3d>(gradient).noalias() = b.pose.R * g;
    }
  }
  return best;
}

int SceneSdf::add_primitive(const Primitive& primitive, const core::Transform& pose) {
  primitive.validate("SceneSdf primitive");
  if (bodies_.size() >= 63) throw std::invalid_argument("SceneSdf: at most 63 objects (exclusion masks are 64-bit)");
  Body b;
  b.primitive = primitive;
  b.pose = pose;
  b.inverse = pose.inverse();
  const Eigen::AlignedBox3d box = primitive.bounds();
  b.lo = box.min();
  b.hi = box.max();
  bodies_.push_back(std::move(b));
  merged_.clear();
  return static_cast<int>(bodies_.size()) - 1;
}

void SceneSdf::set_table(const Eigen::Vector3d& size, const core::Transform& pose) {
  if ((size.array() <= 0).any() || !size.allFinite())
    throw std::invalid_argument("SceneSdf: table size must be positive");
  has_table_ = true;
  table_half_ = size / 2;
  table_pose_ = pose;
  table_inverse_ = pose.inverse();
  table_axis_aligned_ = pose.R.isIdentity(1e-15);
}

namespace {
// Lower bound of a body's distance over the ball (x, radius): the gap to its surface box, less
// one grid resolution for the interpolation; nothing (-inf) once the ball reaches the box,
// since the inside can be arbitrarily deep.
double box_gap_bound(const SceneSdf::Body& b, const Eigen::Vector3d& x, double radius) {
  const double gap = std::sqrt(box_gap2(b, b.inverse.apply(x))) - radius;
  return gap > 0 ? gap - b.slack : -std::numeric_limits<double>::infinity();
}
}  // namespace

double SceneSdf::table_distance(const Eigen::Vector3d& x, Eigen::Vector3d* gradient) const {
  const Eigen::Vector3d xl = table_axis_aligned_ ? Eigen::Vector3d(x - table_pose_.p) : table_inverse_.apply(x);
  // Most queried points are above the top face, inside its footprint: the distance is the height.
  if (xl.z() >= table_half_.z() && std::abs(xl.x()) <= table_half_.x() && std::abs(xl.y()) <= table_half_.y()) {
    if (gradient) *gradient = table_pose_.R.col(2);
    return xl.z() - table_half_.z();
  }
  Eigen::Vector3d g;
  const double d = box_signed_distance(xl, table_half_, gradient ? &g : nullptr);
  if (gradient) gradient->noalias() = table_pose_.R * g;
  return d;
}

double SceneSdf::distance(const Eigen::Vector3d& x, Eigen::Vector3d* gradient, double cutoff,
                          std::uint64_t exclude_mask) const {
  const MergedSdf* merged = use_merged(exclude_mask, cutoff);
  if (!merged) return distance_unmerged(x, gradient, cutoff, exclude_mask);
  return merged_distance(*merged, x.data(), gradient ? gradient->data() : nullptr, cutoff,
                         has_table_ && !(exclude_mask & kTableBit), live_included(exclude_mask));
}

namespace {
// The region a merged grid covers: every included object's surface box, padded so that beyond it
// each object is beyond the cutoff (grid slack included). Throws when it would hold too many bricks.
void merged_region(const std::vector<SceneSdf::Body>& bodies, const std::vector<int>& included,
                   const MergedSdfSettings& settings, Eigen::Vector3d& lo, Eigen::Vector3d& hi) {
  double pad = settings.cutoff + settings.resolution;
  for (const SceneSdf::Body& b : bodies) pad = std::max(pad, settings.cutoff + b.slack);
  lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  hi = -lo;
  for (int i : included) {
    const SceneSdf::Body& b = bodies[i];
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d corner((c & 1) ? b.hi.x() : b.lo.x(), (c & 2) ? b.hi.y() : b.lo.y(),
                                   (c & 4) ? b.hi.z() : b.lo.z());
      const Eigen::Vector3d w = b.pose.apply(corner);
      lo = lo.cwiseMin(w);
      hi = hi.cwiseMax(w);
    }
  }
  if (!lo.allFinite()) lo = hi = Eigen::Vector3d::Zero();  // nothing to merge: every lookup is empty
  lo.array() -= pad;
  hi.array() += pad;
  const double cell_edge = settings.brick * settings.resolution;
  const double cells = ((hi - lo) / cell_edge).array().ceil().prod();
  if (cells > 5e7)
    throw std::invalid_argument("merged SDF: the objects span too large a region for resolution " +
                                std::to_string(settings.resolution) + " m (" + std::to_string(cells) + " bricks)");
}

// Fills one brick (corner node first, x fastest) with the nearest body's distance, capped at the
// cutoff; false when the whole brick is at the cutoff. Only bodies that may be the nearest
// somewhere in the brick's ball (center, radius) are evaluated at its nodes: within the cutoff by
// their box gap, and not dominated by another body's distance interval at the centre (a grid
// interpolant changes by at most sqrt(3) per unit; 2 leaves slack).
bool fill_brick(const std::vector<SceneSdf::Body>& bodies, const MergedSdfSettings& s, const Eigen::Vector3d& corner,
                const Eigen::Vector3d& center, double radius, float* out) {
  int ids[64];
  double at_center[64];
  int count = 0;
  double best_upper = s.cutoff;
  for (int i = 0; i < static_cast<int>(bodies.size()); ++i) {
    if (box_gap_bound(bodies[i], center, radius) >= s.cutoff) continue;
    const SceneSdf::Body& b = bodies[i];
    at_center[count] = b.local_distance(b.inverse.apply(center));
    best_upper = std::min(best_upper, at_center[count] + 2 * radius);
    ids[count++] = i;
  }
  int n_near = 0;
  for (int c = 0; c < count; ++c)
    if (at_center[c] - 2 * radius < best_upper) ids[n_near++] = ids[c];
  if (n_near == 0) return false;
  bool any_inside = false;
  long k = 0;
  const int B = s.brick;
  for (int z = 0; z <= B; ++z)
    for (int y = 0; y <= B; ++y)
      for (int x = 0; x <= B; ++x, ++k) {
        const Eigen::Vector3d node = corner + Eigen::Vector3d(x, y, z) * s.resolution;
        double d = s.cutoff;
        for (int c = 0; c < n_near; ++c) {
          const SceneSdf::Body& b = bodies[ids[c]];
          d = std::min(d, b.local_distance(b.inverse.apply(node)));
        }
        out[k] = static_cast<float>(d);
        any_inside |= d < s.cutoff;
      }
  return any_inside;
}
}  // namespace

void SceneSdf::merge(std::uint64_t exclude_mask, const MergedSdfSettings& settings) {
  if (!(settings.resolution > 0) || !std::isfinite(settings.resolution) || !(settings.cutoff > 0) ||
      !std::isfinite(settings.cutoff) || settings.brick < 1 || settings.brick > 64)
    throw std::invalid_argument("merged SDF: resolution and cutoff must be finite and > 0, brick in [1, 64]");
  exclude_mask = (exclude_mask | live_) & ~kTableBit;
  if (!merged(exclude_mask) && num_merged() >= kMaxMerged)
    throw std::invalid_argument("merged SDF: at most " + std::to_string(kMaxMerged) + " object masks per scene");
  std::vector<int> included;
  for (int i = 0; i < num_objects(); ++i)
    if (!(exclude_mask >> i & 1)) included.push_back(i);
  Eigen::Vector3d lo, hi;
  merged_region(bodies_, included, settings, lo, hi);
  // The brick filler outlives this call (bricks fill on first lookup): it owns copies of the
  // included bodies (their grids are shared, immutable).
  std::vector<Body> bodies;
  for (int i : included) bodies.push_back(bodies_[i]);
  const MergedSdfSettings s = settings;
  auto fill = [bodies, s](const Eigen::Vector3d& corner, const Eigen::Vector3d& center, double radius, float* out) {
    return fill_brick(bodies, s, corner, center, radius, out);
  };
  const auto lower_bound = [&](const Eigen::Vector3d& center, double radius) {
    double best = std::numeric_limits<double>::infinity();
    for (int i : included) best = std::min(best, box_gap_bound(bodies_[i], center, radius));
    return best;
  };
  auto grid = std::make_shared<const MergedSdf>(MergedSdf::build(lo, hi, settings, exclude_mask, fill, lower_bound));
  for (auto& m : merged_)
    if (m->exclude_mask() == grid->exclude_mask()) {
      m = std::move(grid);
      return;
    }
  merged_.push_back(std::move(grid));
}

SceneSdf::PartBounds SceneSdf::part_lower_bounds(const Eigen::Vector3d& x, std::uint64_t exclude_mask) const {
  PartBounds b{std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity()};
  if (const MergedSdf* merged = use_merged(exclude_mask, 0.0)) {
    b.objects = merged->lower_bound(x.data());
    std::uint64_t live = live_included(exclude_mask);
    for (int i = 0; live; ++i, live >>= 1)
      if (live & 1) b.objects = std::min(b.objects, box_gap_bound(bodies_[i], x, 0.0));
  } else {
    for (int i = 0; i < num_objects(); ++i) {
      if (!(exclude_mask >> i & 1)) b.objects = std::min(b.objects, box_gap_bound(bodies_[i], x, 0.0));
    }
  }
  if (has_table_ && !(exclude_mask & kTableBit)) b.table = table_distance(x, nullptr);
  return b;
}

double SceneSdf::lower_bound(const Eigen::Vector3d& x, std::uint64_t exclude_mask) const {
  const PartBounds b = part_lower_bounds(x, exclude_mask);
  return std::min(b.objects, b.table);
}

double SceneSdf::distance_unmerged(const Eigen::Vector3d& x, Eigen::Vector3d* gradient, double cutoff,
                                   std::uint64_t exclude_mask) const {
  double best = cutoff;
  Eigen::Vector3d best_grad = Eigen::Vector3d::Zero();
  Eigen::Vector3d g;
  // Gap from x to each body's surface box: a lower bound of its distance. Visiting the bodies
  // nearest-box-first lets the running minimum skip most grid lookups (each one a cache miss).
  const int n = static_cast<int>(bodies_.size());
  double gap2[64];
  int order[64];
  int m = 0;
  for (int i = 0; i < n; ++i) {
    if (exclude_mask >> i & 1) continue;
    const Body& b = bodies_[i];
    const double g2 = box_gap2(b, b.inverse.apply(x));
    if (g2 > 0 && best > 0 && g2 >= best * best) continue;  // farther than the cutoff
    int k = m++;
    for (; k > 0 && gap2[order[k - 1]] > g2; --k) order[k] = order[k - 1];
    order[k] = i;
    gap2[i] = g2;
  }
  for (int j = 0; j < m; ++j) {
    const int i = order[j];
    if (gap2[i] > 0 && (best <= 0 || gap2[i] >= best * best)) break;  // sorted: the rest are farther
    const Body& b = bodies_[i];
    const double d = b.local_distance(b.inverse.apply(x), gradient ? &g : nullptr);
    if (d < best) {
      best = d;
      if (gradient) best_grad.noalias() = b.pose.R * g;
    }
  }
  if (has_table_ && !(exclude_mask & kTableBit)) {
    const double d = table_distance(x, gradient ? &g : nullptr);
    if (d < best) {
      best = d;
      if (gradient) best_grad = g;
    }
  }
  if (gradient) *gradient = best_grad;
  return best;
}

void SceneSdf::distances(const double* points, long n, double* dist, double* grad, double cutoff,
                         std::uint64_t exclude_mask, bool objects, bool table) const {
  table = table && has_table_ && !(exclude_mask & kTableBit);
  if (!objects) {
    Eigen::Vector3d g;
    for (long i = 0; i < n; ++i) {
      double d = cutoff;
      g.setZero();
      if (table) {
        Eigen::Vector3d gt = Eigen::Vector3d::Zero();
        const double dt = table_distance(Eigen::Map<const Eigen::Vector3d>(points + 3 * i), grad ? &gt : nullptr);
        if (dt < d) d = dt, g = gt;
      }
      dist[i] = d;
      if (grad) Eigen::Map<Eigen::Vector3d>(grad + 3 * i) = g;
    }
    return;
  }
  if (const MergedSdf* merged = use_merged(exclude_mask, cutoff)) {
    // The hot path, with the per-point dispatch hoisted out of the loop.
    const std::uint64_t live = live_included(exclude_mask);
    for (long i = 0; i < n; ++i)
      dist[i] = merged_distance(*merged, points + 3 * i, grad ? grad + 3 * i : nullptr, cutoff, table, live);
    return;
  }
  const std::uint64_t mask = table ? exclude_mask : exclude_mask | kTableBit;
  Eigen::Vector3d g;
  for (long i = 0; i < n; ++i) {
    const Eigen::Map<const Eigen::Vector3d> x(points + 3 * i);
    dist[i] = distance(x, grad ? &g : nullptr, cutoff, mask);
    if (grad) Eigen::Map<Eigen::Vector3d>(grad + 3 * i) = g;
  }
}

}  // namespace pickplan::geometry
