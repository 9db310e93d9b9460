// Building an SdfGrid from a triangle mesh.
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "pickplan/core/errors.hpp"
#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {
namespace {

struct Triangle {
  Eigen::Vector3d a, b, c;
};

// Closest point on triangle abc to p (Ericson, Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closest_on_triangle(const Eigen::Vector3d& p, const Triangle& t) {
  const Eigen::Vector3d ab = t.b - t.a, ac = t.c - t.a, ap = p - t.a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return t.a;
  const Eigen::Vector3d bp = p - t.b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return t.b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return t.a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - t.c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return t.c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return t.a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return t.b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (t.c - t.b);
  const double denom = 1.0 / (va + vb + vc);
  return t.a + ab * (vb * denom) + ac * (vc * denom);
}

double point_triangle_distance(const Eigen::Vector3d& p, const Triangle& t) {
  return (p - closest_on_triangle(p, t)).norm();
}

struct Grid {
  Eigen::Vector3d origin;
  double res;
  int nx, ny, nz;
  long index(int i, int j, int k) const { return (static_cast<long>(k) * ny + j) * nx + i; }
  Eigen::Vector3d node(int i, int j, int k) const { return origin + res * Eigen::Vector3d(i, j, k); }
};

// Unsigned distance: exact in a band around each triangle, then closest-triangle propagation.
void unsigned_distance(const Grid& g, const std::vector<Triangle>& tris, std::vector<float>& dist) {
  const long n = static_cast<long>(g.nx) * g.ny * g.nz;
  std::vector<double> d(n, std::numeric_limits<double>::infinity());
  std::vector<int> closest(n, -1);
  const double band = 1.5 * g.res;
  for (int t = 0; t < static_cast<int>(tris.size()); ++t) {
    const Triangle& tri = tris[t];
    Eigen::Vector3d lo = tri.a.cwiseMin(tri.b).cwiseMin(tri.c).array() - band;
    Eigen::Vector3d hi = tri.a.cwiseMax(tri.b).cwiseMax(tri.c).array() + band;
    Eigen::Vector3i ilo = ((lo - g.origin) / g.res).array().ceil().cast<int>().max(0);
    Eigen::Vector3i ihi =
        ((hi - g.origin) / g.res).array().floor().cast<int>().min(Eigen::Array3i(g.nx - 1, g.ny - 1, g.nz - 1));
    for (int k = ilo.z(); k <= ihi.z(); ++k)
      for (int j = ilo.y(); j <= ihi.y(); ++j)
        for (int i = ilo.x(); i <= ihi.x(); ++i) {
          const long id = g.index(i, j, k);
          const double dd = point_triangle_distance(g.node(i, j, k), tri);
          if (dd < d[id]) {
            d[id] = dd;
            closest[id] = t;
          }
        }
  }
  // Fast sweeping in the 8 diagonal orders, twice: each node tries its neighbours' triangles.
  for (int round = 0; round < 2; ++round)
    for (int s = 0; s < 8; ++s) {
      const int sx = (s & 1) ? -1 : 1, sy = (s & 2) ? -1 : 1, sz = (s & 4) ? -1 : 1;
      for (int kk = 0; kk < g.nz; ++kk) {
        const int k = sz > 0 ? kk : g.nz - 1 - kk;
        for (int jj = 0; jj < g.ny; ++jj) {
          const int j = sy > 0 ? jj : g.ny - 1 - jj;
          for (int ii = 0; ii < g.nx; ++ii) {
            const int i = sx > 0 ? ii : g.nx - 1 - ii;
            const long id = g.index(i, j, k);
            const std::array<long, 3> nbr = {(i - sx >= 0 && i - sx < g.nx) ? g.index(i - sx, j, k) : -1,
                                             (j - sy >= 0 && j - sy < g.ny) ? g.index(i, j - sy, k) : -1,
                                             (k - sz >= 0 && k - sz < g.nz) ? g.index(i, j, k - sz) : -1};
            for (long nb : nbr) {
              if (nb < 0) continue;
              const int t = closest[nb];
              if (t < 0 || t == closest[id]) continue;
              const double dd = point_triangle_distance(g.node(i, j, k), tris[t]);
              if (dd < d[id]) {
                d[id] = dd;
                closest[id] = t;
              }
            }
          }
        }
      }
    }
  dist.resize(n);
  for (long i = 0; i < n; ++i) dist[i] = static_cast<float>(d[i]);
}

// Inside/outside by ray parity along each axis through the grid nodes; majority of 3 votes.
std::vector<signed char> inside_votes(const Grid& g, const std::vector<Triangle>& tris, double* disagreement) {
  const long n = static_cast<long>(g.nx) * g.ny * g.nz;
  std::vector<signed char> votes(n, 0);
  const int dims[3] = {g.nx, g.ny, g.nz};
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    const int nu = dims[u], nv = dims[v], na = dims[axis];
    std::vector<std::vector<double>> hits(static_cast<size_t>(nu) * nv);
    for (const Triangle& t : tris) {
      const Eigen::Vector3d P[3] = {t.a, t.b, t.c};
      double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
      for (const auto& p : P) {
        umin = std::min(umin, p[u]);
        umax = std::max(umax, p[u]);
        vmin = std::min(vmin, p[v]);
        vmax = std::max(vmax, p[v]);
      }
      const int i0 = std::max(0, static_cast<int>(std::ceil((umin - g.origin[u]) / g.res)));
      const int i1 = std::min(nu - 1, static_cast<int>(std::floor((umax - g.origin[u]) / g.res)));
      const int j0 = std::max(0, static_cast<int>(std::ceil((vmin - g.origin[v]) / g.res)));
      const int j1 = std::min(nv - 1, static_cast<int>(std::floor((vmax - g.origin[v]) / g.res)));
      for (int j = j0; j <= j1; ++j)
        for (int i = i0; i <= i1; ++i) {
          // Rays pass slightly off the node lattice so they do not graze shared edges exactly.
          const double pu = g.origin[u] + i * g.res + 1.3e-7 * g.res, pv = g.origin[v] + j * g.res + 0.7e-7 * g.res;
          const double e0 = (P[1][u] - P[0][u]) * (pv - P[0][v]) - (P[1][v] - P[0][v]) * (pu - P[0][u]);
          const double e1 = (P[2][u] - P[1][u]) * (pv - P[1][v]) - (P[2][v] - P[1][v]) * (pu - P[1][u]);
          const double e2 = (P[0][u] - P[2][u]) * (pv - P[2][v]) - (P[0][v] - P[2][v]) * (pu - P[2][u]);
          if (!((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0))) continue;
          const double area = e0 + e1 + e2;
          if (std::abs(area) < 1e-300) continue;
          // Barycentric weights: e1 pairs with vertex 0, e2 with 1, e0 with 2.
          const double h = (e1 * P[0][axis] + e2 * P[1][axis] + e0 * P[2][axis]) / area;
          hits[static_cast<size_t>(j) * nu + i].push_back(h);
        }
    }
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        auto& hv = hits[static_cast<size_t>(j) * nu + i];
        if (hv.empty()) continue;
        std::sort(hv.begin(), hv.end());
        size_t passed = 0;
        for (int a = 0; a < na; ++a) {
          const double pa = g.origin[axis] + a * g.res;
          while (passed < hv.size() && hv[passed] < pa) ++passed;
          if (passed % 2 == 1) {
            int idx[3];
            idx[axis] = a;
            idx[u] = i;
            idx[v] = j;
            votes[g.index(idx[0], idx[1], idx[2])] += 1;
          }
        }
      }
  }
  long mixed = 0;
  for (long i = 0; i < n; ++i) mixed += (votes[i] == 1 || votes[i] == 2);
  if (disagreement) *disagreement = n ? static_cast<double>(mixed) / n : 0.0;
  return votes;
}

}  // namespace

SdfGrid SdfGrid::build(const Vertices& V, const Faces& F, const SdfBuildSettings& s, SdfBuildReport* report) {
  if (V.rows() == 0 || F.rows() == 0) throw std::invalid_argument("SDF mesh: empty mesh (no vertices or no faces)");
  core::require_finite("SDF mesh vertices", V.data(), V.size());
  if (!(s.resolution > 0) || !(s.margin >= 0) || !std::isfinite(s.resolution) || !std::isfinite(s.margin))
    throw std::invalid_argument("SDF settings: resolution must be > 0 and margin >= 0");
  std::vector<Triangle> tris;
  tris.reserve(F.rows());
  int degenerate = 0;
  for (int f = 0; f < F.rows(); ++f) {
    for (int c = 0; c < 3; ++c)
      if (F(f, c) < 0 || F(f, c) >= V.rows()) {
        std::ostringstream msg;
        msg << "SDF mesh: face " << f << " refers to vertex " << F(f, c) << " but there are " << V.rows()
            << " vertices";
        throw std::invalid_argument(msg.str());
      }
    Triangle t{V.row(F(f, 0)).transpose(), V.row(F(f, 1)).transpose(), V.row(F(f, 2)).transpose()};
    if ((t.b - t.a).cross(t.c - t.a).norm() < 1e-14) {
      ++degenerate;
      continue;
    }
    tris.push_back(t);
  }
  if (tris.empty()) throw std::invalid_argument("SDF mesh: degenerate (every face has zero area)");
  const Eigen::Vector3d lo = V.colwise().minCoeff().transpose(), hi = V.colwise().maxCoeff().transpose();
  Grid g;
  g.res = s.resolution;
  g.origin = lo.array() - s.margin;
  const Eigen::Vector3d extent = (hi - lo).array() + 2 * s.margin;
  g.nx = static_cast<int>(std::ceil(extent.x() / g.res)) + 1;
  g.ny = static_cast<int>(std::ceil(extent.y() / g.res)) + 1;
  g.nz = static_cast<int>(std::ceil(extent.z() / g.res)) + 1;
  if (static_cast<double>(g.nx) * g.ny * g.nz > 2e8)
    throw std::invalid_argument("SDF grid would have more than 2e8 nodes: raise the resolution value");
  std::vector<float> dist;
  unsigned_distance(g, tris, dist);
  double disagreement = 0;
  auto votes = inside_votes(g, tris, &disagreement);
  for (size_t i = 0; i < dist.size(); ++i)
    if (votes[i] >= 2) dist[i] = -dist[i];
  if (report) {
    report->degenerate_faces = degenerate;
    report->sign_disagreement = disagreement;
  }
  return from_values(g.origin, g.res, Eigen::Vector3i(g.nx, g.ny, g.nz), std::move(dist));
}

SdfGrid SdfGrid::from_values(const Eigen::Vector3d& origin, double resolution, const Eigen::Vector3i& dims,
                             std::vector<float> values) {
  if (dims.minCoeff() < 2) throw std::invalid_argument("SDF grid: every dimension needs at least 2 nodes");
  if (!(resolution > 0)) throw std::invalid_argument("SDF grid: resolution must be > 0");
  const long n = static_cast<long>(dims.x()) * dims.y() * dims.z();
  core::require_size("SDF grid values", n, static_cast<long>(values.size()));
  SdfGrid grid;
  grid.origin_ = origin;
  grid.resolution_ = resolution;
  grid.dims_ = dims;
  grid.values_ = std::move(values);
  grid.compute_surface_box();
  return grid;
}

void SdfGrid::compute_surface_box() {
  Eigen::Vector3i lo = dims_, hi = Eigen::Vector3i::Constant(-1);
  const float near = static_cast<float>(resolution_);
  for (int k = 0; k < dims_.z(); ++k)
    for (int j = 0; j < dims_.y(); ++j)
      for (int i = 0; i < dims_.x(); ++i)
        if (values_[(static_cast<long>(k) * dims_.y() + j) * dims_.x() + i] < near) {
          lo = lo.cwiseMin(Eigen::Vector3i(i, j, k));
          hi = hi.cwiseMax(Eigen::Vector3i(i, j, k));
        }
  if (hi.x() < 0) {  // nothing near a surface: fall back to the whole grid
    surface_lo_ = origin_;
    surface_hi_ = upper();
    return;
  }
  surface_lo_ = origin_ + (lo.cast<double>().array() - 1.0).matrix() * resolution_;
  surface_hi_ = origin_ + (hi.cast<double>().array() + 1.0).matrix() * resolution_;
}

}  // namespace pickplan::geometry
