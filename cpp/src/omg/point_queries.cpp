#include "pickplan/omg/point_queries.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <unordered_map>

namespace pickplan::omg {

namespace {

// Points bucketed in cubic cells of edge `cell` (each cell's points in ascending index order).
class CellIndex {
 public:
  CellIndex(const RowMatrixXd& P, double cell) : P_(P), inv_(1.0 / cell) {
    for (long k = 0; k < P.rows(); ++k) cells_[key(cell_of(k, 0), cell_of(k, 1), cell_of(k, 2))].push_back(k);
  }
  long cell_of(long k, int axis) const { return static_cast<long>(std::floor(P_(k, axis) * inv_)); }
  const std::vector<long>* at(long x, long y, long z) const {
    const auto it = cells_.find(key(x, y, z));
    return it == cells_.end() ? nullptr : &it->second;
  }

 private:
  static std::int64_t key(long x, long y, long z) {
    return (static_cast<std::int64_t>(x) * 73856093) ^ (static_cast<std::int64_t>(y) * 19349663) ^
           (static_cast<std::int64_t>(z) * 83492791);
  }
  const RowMatrixXd& P_;
  double inv_;
  // cells that share a hashed key share a bucket: the distance test sorts them out
  std::unordered_map<std::int64_t, std::vector<long>> cells_;
};

}  // namespace

namespace {

// visit(i, j) for every pair radius_pairs finds, in its order.
template <class Visit>
void visit_radius_pairs(const RowMatrixXd& points, const std::vector<long>& queries, double radius,
                        const std::vector<std::uint8_t>& keep, const std::vector<long>& order, Visit&& visit) {
  if (points.cols() != 3) throw std::invalid_argument("radius pairs: expected (N, 3) points");
  if (!(std::isfinite(radius) && radius > 0)) throw std::invalid_argument("radius pairs: radius must be > 0");
  if (!points.allFinite()) throw std::invalid_argument("radius pairs: points must be finite");
  if (!keep.empty() && static_cast<long>(keep.size()) != points.rows())
    throw std::invalid_argument("radius pairs: expected one keep flag per point, got " + std::to_string(keep.size()));
  for (long q : queries)
    if (q < 0 || q >= points.rows())
      throw std::invalid_argument("radius pairs: query index " + std::to_string(q) + " out of range");
  const long n = points.rows();
  std::vector<long> sequence = order, rank(static_cast<std::size_t>(n), -1);  // a point's place in the order
  if (sequence.empty())
    for (long k = 0; k < n; ++k) sequence.push_back(k);
  if (static_cast<long>(sequence.size()) != n)
    throw std::invalid_argument("radius pairs: the order must hold every point once");
  for (long t = 0; t < n; ++t) {
    const long k = sequence[t];
    if (k < 0 || k >= n || rank[k] >= 0)
      throw std::invalid_argument("radius pairs: the order must hold every point once");
    rank[k] = t;
  }
  if (n == 0) return;
  const CellIndex cells(points, radius);
  const double r2 = radius * radius;
  std::vector<long> found;
  std::vector<std::uint8_t> marked(static_cast<std::size_t>(points.rows()), 0);
  for (long i : queries) {
    found.clear();
    const long cx = cells.cell_of(i, 0), cy = cells.cell_of(i, 1), cz = cells.cell_of(i, 2);
    const double x = points(i, 0), y = points(i, 1), z = points(i, 2);
    for (long dz = -1; dz <= 1; ++dz)
      for (long dy = -1; dy <= 1; ++dy)
        for (long dx = -1; dx <= 1; ++dx) {
          const std::vector<long>* bucket = cells.at(cx + dx, cy + dy, cz + dz);
          if (!bucket) continue;
          for (long j : *bucket) {
            if (!keep.empty() && !keep[j]) continue;
            const double ex = points(j, 0) - x, ey = points(j, 1) - y, ez = points(j, 2) - z;
            if (ex * ex + ey * ey + ez * ez <= r2) found.push_back(j);
          }
        }
    // in the order, once each (a hash collision can read one bucket twice): few found are sorted; many
    // (a radius as large as the cloud) are marked and read back in the order
    if (found.size() * 16 < marked.size()) {
      std::sort(found.begin(), found.end(), [&](long a, long b) { return rank[a] < rank[b]; });
      found.erase(std::unique(found.begin(), found.end()), found.end());
    } else {
      for (long j : found) marked[j] = 1;
      found.clear();
      for (long j : sequence)
        if (marked[j]) found.push_back(j), marked[j] = 0;
    }
    for (long j : found) visit(i, j);
  }
}

}  // namespace

RadiusPairs radius_pairs(const RowMatrixXd& points, const std::vector<long>& queries, double radius,
                         const std::vector<std::uint8_t>& keep, const std::vector<long>& order) {
  RadiusPairs out;
  visit_radius_pairs(points, queries, radius, keep, order,
                     [&](long i, long j) { out.i.push_back(i), out.j.push_back(j); });
  return out;
}

AntipodalPartners antipodal_partners(const RowMatrixXd& points, const RowMatrixXd& normals,
                                     const std::vector<long>& queries, double radius,
                                     const std::vector<std::uint8_t>& keep, const std::vector<long>& order,
                                     double min_width, double cone) {
  if (normals.rows() != points.rows() || normals.cols() != 3)
    throw std::invalid_argument("antipodal partners: expected (N, 3) normals like the points");
  AntipodalPartners out;
  double margin = 0, width = 0;
  visit_radius_pairs(points, queries, radius, keep, order, [&](long i, long j) {
    if (!antipodal_pair(points, normals, i, j, min_width, cone, &margin, &width)) return;
    out.i.push_back(i), out.j.push_back(j), out.margins.push_back(margin), out.widths.push_back(width);
  });
  return out;
}

}  // namespace pickplan::omg
