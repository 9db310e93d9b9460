#include "pickplan/perception/depth_field.hpp"

#include "pickplan/geometry/point_index.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace pickplan::perception {

namespace {

enum class VoxelState : std::uint8_t { kNone = 0, kOccupied = 1, kTarget = 2, kFree = 3 };  // by priority

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

void validate_view(const DepthView& v, std::size_t k) {
  const std::string w = "depth view " + std::to_string(k) + ": ";
  require(v.depth.rows() > 1 && v.depth.cols() > 1, w + "expected an H x W depth image, got " +
                                                        std::to_string(v.depth.rows()) + " x " +
                                                        std::to_string(v.depth.cols()));
  require(v.target.size() == 0 || (v.target.rows() == v.depth.rows() && v.target.cols() == v.depth.cols()),
          w + "target mask is " + std::to_string(v.target.rows()) + " x " + std::to_string(v.target.cols()) +
              ", the depth image " + std::to_string(v.depth.rows()) + " x " + std::to_string(v.depth.cols()));
  require(v.K.allFinite() && v.K(0, 0) > 0 && v.K(1, 1) > 0 && v.K(2, 2) == 1.0 && v.K(2, 0) == 0 && v.K(2, 1) == 0,
          w + "intrinsics must be [[fx, s, cx], [0, fy, cy], [0, 0, 1]] with fx, fy > 0");
  const Eigen::Matrix3d& R = v.camera_pose.R;
  require(v.camera_pose.p.allFinite() && R.allFinite() &&
              (R * R.transpose() - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < 1e-6 && R.determinant() > 0,
          w + "camera pose is not a rigid transform");
}

// One 1-D pass of the squared distance transform: the lower envelope of the parabolas
// (q - p)^2 + f[p] (Felzenszwalb and Huttenlocher, 2012). v: parabola apexes, z: envelope breaks.
void dt_1d(const float* f, float* d, int n, int* v, float* z) {
  auto cross = [&](int q, int p) {
    return ((f[q] + float(q) * float(q)) - (f[p] + float(p) * float(p))) / (2.0f * float(q - p));
  };
  int k = 0;
  v[0] = 0;
  z[0] = -std::numeric_limits<float>::infinity();
  z[1] = std::numeric_limits<float>::infinity();
  for (int q = 1; q < n; ++q) {
    float s = cross(q, v[k]);
    while (s <= z[k]) {  // z[0] = -inf ends the loop at k = 0
      --k;
      s = cross(q, v[k]);
    }
    ++k;
    v[k] = q;
    z[k] = s;
    z[k + 1] = std::numeric_limits<float>::infinity();
  }
  k = 0;
  for (int q = 0; q < n; ++q) {
    while (z[k + 1] < float(q)) ++k;
    const float dq = float(q - v[k]);
    d[q] = dq * dq + f[v[k]];
  }
}

// One view's verdict on every voxel (the header's rule), merged into `state` by priority. The voxel's
// camera-frame position is affine in its index: a row's start is transformed once and stepped along x.
// Each row is projected first and its pixels prefetched, then read: the depth image does not fit the
// cache, and a row's voxels land on pixels scattered across it.
void carve(const DepthView& view, const DepthFieldSettings& s, const Eigen::Vector3i& dims,
           std::vector<std::uint8_t>* state) {
  const Eigen::Matrix3d Rt = view.camera_pose.R.transpose();
  const Eigen::Vector3d origin = Rt * (s.lo - view.camera_pose.p), step = s.resolution * Rt.col(0);
  const double fx = view.K(0, 0), fy = view.K(1, 1), cx = view.K(0, 2), cy = view.K(1, 2), sk = view.K(0, 1);
  const long H = view.depth.rows(), W = view.depth.cols();
  const float* depth = view.depth.data();
  const std::uint8_t* target = view.target.size() > 0 ? view.target.data() : nullptr;
  std::vector<long> pixels(dims.x());   // per voxel of the row: its pixel, -1 outside the view
  std::vector<double> along(dims.x());  // and its depth along the optical axis
  for (int kz = 0; kz < dims.z(); ++kz)
    for (int ky = 0; ky < dims.y(); ++ky) {
      std::uint8_t* st = state->data() + (static_cast<long>(kz) * dims.y() + ky) * dims.x();
      const Eigen::Vector3d p0 = origin + s.resolution * (ky * Rt.col(1) + kz * Rt.col(2));
      long seen = 0;
      for (int kx = 0; kx < dims.x(); ++kx) {
        const double px = p0.x() + kx * step.x(), py = p0.y() + kx * step.y(), pz = p0.z() + kx * step.z();
        pixels[kx] = -1;
        if (pz <= 1e-6) continue;
        const double iz = 1.0 / pz;
        const double u = (fx * px + sk * py) * iz + cx, v = fy * py * iz + cy;
        if (!(u >= 0 && v >= 0 && u < W && v < H)) continue;
        pixels[kx] = static_cast<long>(v) * W + static_cast<long>(u);
        along[kx] = pz;
        __builtin_prefetch(depth + pixels[kx]);
        ++seen;
      }
      if (seen == 0) continue;
      for (int kx = 0; kx < dims.x(); ++kx) {
        const long pixel = pixels[kx];
        if (pixel < 0) continue;
        const float d = depth[pixel];
        if (!(std::isfinite(d) && d > 0)) continue;
        VoxelState c;
        if (along[kx] < d - s.surface_margin)
          c = VoxelState::kFree;
        else if (target && target[pixel])
          c = VoxelState::kTarget;
        else
          c = VoxelState::kOccupied;
        st[kx] = std::max(st[kx], static_cast<std::uint8_t>(c));
      }
    }
}

// Inside the occupied voxels: minus the distance to the nearest free node plus half a voxel. The
// distance transform runs over the occupied voxels' bounding box grown by one voxel (within the
// grid) only: that shell holds no occupied voxel, and any free voxel beyond it is farther than the
// shell voxel nearest to it along each axis, so the box's transform is the whole grid's (exact).
void inside_distances(const std::vector<std::uint8_t>& occupied, const Eigen::Vector3i& dims, Eigen::Vector3i lo,
                      Eigen::Vector3i hi, double res, std::vector<float>* values) {
  lo = (lo.array() - 1).max(0).matrix();
  hi = (hi.array() + 1).min(dims.array() - 1).matrix();
  const Eigen::Vector3i sub = hi - lo + Eigen::Vector3i::Ones();
  std::vector<std::uint8_t> outside(static_cast<long>(sub.prod()));
  auto index = [&](int x, int y, int z) { return (static_cast<long>(z) * dims.y() + y) * dims.x() + x; };
  long k = 0;
  for (int z = lo.z(); z <= hi.z(); ++z)
    for (int y = lo.y(); y <= hi.y(); ++y)
      for (int x = lo.x(); x <= hi.x(); ++x) outside[k++] = !occupied[index(x, y, z)];
  const std::vector<float> to_free = squared_distance_transform(outside, sub);
  const float half = static_cast<float>(0.5 * res);
  k = 0;
  for (int z = lo.z(); z <= hi.z(); ++z)
    for (int y = lo.y(); y <= hi.y(); ++y)
      for (int x = lo.x(); x <= hi.x(); ++x, ++k)
        if (occupied[index(x, y, z)]) (*values)[index(x, y, z)] = -(std::sqrt(to_free[k]) * float(res) - half);
}

}  // namespace

void DepthFieldSettings::validate() const {
  require(lo.allFinite() && hi.allFinite() && (hi - lo).minCoeff() > 0, "depth field: workspace box needs lo < hi");
  require(std::isfinite(resolution) && resolution > 1e-4, "depth field: resolution must be > 0.1 mm");
  const Eigen::Vector3d n = (hi - lo) / resolution;
  require(n.prod() < 2.0e8, "depth field: more than 2e8 voxels; coarsen the resolution or shrink the box");
  require(std::isfinite(surface_margin) && surface_margin >= 0, "depth field: surface_margin must be >= 0");
  require(!has_plane ||
              (plane_normal.allFinite() && std::abs(plane_normal.norm() - 1) < 1e-6 && std::isfinite(plane_offset)),
          "depth field: the support plane needs a unit normal and a finite offset");
  require(target_stride >= 1, "depth field: target_stride must be >= 1");
}

PlaneChoice most_inliers(const geometry::Vertices& points, const geometry::Vertices& normals,
                         const Eigen::VectorXd& offsets, double tolerance) {
  require(offsets.size() == normals.rows(), "plane inliers: expected one offset per normal, got " +
                                                std::to_string(offsets.size()) + " for " +
                                                std::to_string(normals.rows()));
  require(std::isfinite(tolerance) && tolerance >= 0, "plane inliers: tolerance must be >= 0");
  PlaneChoice best;
  const long n = points.rows(), chunk = 512;
  for (long k = 0; k < normals.rows(); ++k) {
    const double nx = normals(k, 0), ny = normals(k, 1), nz = normals(k, 2), d = offsets(k);
    long c = 0;
    for (long start = 0; start < n; start += chunk) {
      // a later hypothesis must have more inliers than the best so far: stop once it cannot
      if (best.index >= 0 && c + (n - start) <= best.inliers) break;
      const long end = std::min(n, start + chunk);
      for (long i = start; i < end; ++i)
        c += std::abs(points(i, 0) * nx + points(i, 1) * ny + points(i, 2) * nz - d) < tolerance;
    }
    if (best.index < 0 || c > best.inliers) best.index = k, best.inliers = c;
  }
  return best;
}

std::vector<float> point_distance_grid(const geometry::Vertices& points, const Eigen::Vector3d& origin,
                                       double resolution, const Eigen::Vector3i& dims) {
  require(points.rows() > 0 && points.allFinite(),
          "point distance grid: expected finite points, got " + std::to_string(points.rows()) + " rows");
  require(dims.minCoeff() >= 1 && static_cast<double>(dims.x()) * dims.y() * dims.z() < 2.0e8,
          "point distance grid: expected 1 to 2e8 nodes");
  require(origin.allFinite() && std::isfinite(resolution) && resolution > 0,
          "point distance grid: bad origin or resolution");
  const geometry::PointIndex index(&points);
  std::vector<float> out(static_cast<std::size_t>(dims.prod()));
  std::size_t k = 0;
  // A neighbouring node's nearest point bounds this node's nearest distance: the search is pruned by it
  // (with a hair of slack for rounding), the same nearest distance found. It is usually the answer.
  auto bounded = [&](const Eigen::Vector3d& q, std::size_t* nearest) {
    double d2 = 0;
    if (*nearest < static_cast<std::size_t>(points.rows())) {
      const double b2 = (points.row(static_cast<Eigen::Index>(*nearest)).transpose() - q).squaredNorm();
      if (index.nearest_within(q.data(), b2 * (1 + 1e-9) + 1e-24, nearest, &d2)) return std::sqrt(d2);
    }
    index.nearest(q.data(), nearest, &d2);
    return std::sqrt(d2);
  };
  const std::size_t none = static_cast<std::size_t>(points.rows());
  std::size_t row_first = none, plane_first = none;  // the first node's nearest point of the previous row, plane
  for (int z = 0; z < dims.z(); ++z)
    for (int y = 0; y < dims.y(); ++y) {
      std::size_t nearest = y > 0 ? row_first : plane_first;
      for (int x = 0; x < dims.x(); ++x, ++k) {
        out[k] = static_cast<float>(bounded(origin + resolution * Eigen::Vector3d(x, y, z), &nearest));
        if (x == 0) {
          row_first = nearest;
          if (y == 0) plane_first = nearest;
        }
      }
    }
  return out;
}

std::vector<float> squared_distance_transform(const std::vector<std::uint8_t>& mask, const Eigen::Vector3i& dims) {
  const long total = static_cast<long>(dims.prod());
  require(dims.minCoeff() >= 1 && static_cast<long>(mask.size()) == total,
          "distance transform: expected " + std::to_string(total) + " mask values, got " + std::to_string(mask.size()));
  const float big = 1e20f;
  std::vector<float> g(total);
  for (long i = 0; i < total; ++i) g[i] = mask[i] ? 0.0f : big;
  const int n_max = dims.maxCoeff();
  std::vector<float> f(n_max), d(n_max), z(n_max + 1);
  std::vector<int> v(n_max);
  // along x the input is binary: the distance to the nearest set voxel in a forward and a backward sweep
  for (long row = 0; row < total; row += dims.x()) {
    float* line = g.data() + row;
    long last = -1;
    for (long q = 0; q < dims.x(); ++q) {
      if (line[q] == 0.0f)
        last = q;
      else if (last >= 0)
        line[q] = float((q - last) * (q - last));
    }
    last = -1;
    for (long q = dims.x() - 1; q >= 0; --q) {
      if (line[q] == 0.0f)
        last = q;
      else if (last >= 0)
        line[q] = std::min(line[q], float((q - last) * (q - last)));
    }
  }
  const long stride[3] = {1, dims.x(), static_cast<long>(dims.x()) * dims.y()};
  // Along y and z, lines 16 x apart at a time: their values are read and written a cache line (16
  // neighbouring x) per step along the line into a small block, and each line transformed there (the
  // lines are independent: the same values as one line at a time, without a cache miss per value).
  constexpr int kBlock = 16;
  std::vector<float> block(static_cast<std::size_t>(n_max) * kBlock);
  for (int axis = 1; axis < 3; ++axis) {
    const int n = dims[axis];
    const int a = axis == 1 ? 2 : 1;  // the other axis
    for (int i = 0; i < dims[a]; ++i)
      for (int x0 = 0; x0 < dims.x(); x0 += kBlock) {
        const int w = std::min(kBlock, dims.x() - x0);
        const long base = i * stride[a] + x0;
        for (int q = 0; q < n; ++q) std::copy_n(g.data() + base + q * stride[axis], w, block.data() + q * kBlock);
        for (int c = 0; c < w; ++c) {
          bool any = false;
          for (int q = 0; q < n; ++q) {
            f[q] = block[q * kBlock + c];
            any = any || f[q] < big;
          }
          if (!any) continue;  // no set voxel in this line's planes yet: it stays far
          dt_1d(f.data(), d.data(), n, v.data(), z.data());
          for (int q = 0; q < n; ++q) block[q * kBlock + c] = std::min(d[q], big);
        }
        for (int q = 0; q < n; ++q) std::copy_n(block.data() + q * kBlock, w, g.data() + base + q * stride[axis]);
      }
  }
  return g;
}

DepthField build_depth_field(const std::vector<DepthView>& views, const DepthFieldSettings& s) {
  s.validate();
  require(!views.empty(), "depth field: no depth views");
  for (std::size_t k = 0; k < views.size(); ++k) validate_view(views[k], k);
  const double res = s.resolution;
  const Eigen::Vector3i dims = (((s.hi - s.lo) / res).array().floor() + 1).cast<int>();
  const long total = static_cast<long>(dims.prod());
  std::vector<std::uint8_t> state(total, static_cast<std::uint8_t>(VoxelState::kNone));

  for (const DepthView& view : views) carve(view, s, dims, &state);

  DepthField out;
  std::vector<std::uint8_t> occupied(total);
  Eigen::Vector3i box_lo = dims, box_hi = Eigen::Vector3i::Constant(-1);  // the occupied voxels' bounds
  // the height above the plane is affine in the voxel index: stepped along each row, not recomputed
  const Eigen::Vector3d n = s.has_plane ? s.plane_normal : Eigen::Vector3d::Zero();
  for (int kz = 0; kz < dims.z(); ++kz)
    for (int ky = 0; ky < dims.y(); ++ky) {
      const long row = (static_cast<long>(kz) * dims.y() + ky) * dims.x();
      const double h0 = n.dot(s.lo + res * Eigen::Vector3d(0, ky, kz)) - s.plane_offset;
      for (int kx = 0; kx < dims.x(); ++kx) {
        const long i = row + kx;
        const bool table = s.has_plane && h0 + res * kx * n.x() < s.plane_margin;
        const auto st = static_cast<VoxelState>(state[i]);
        occupied[i] = !table && st == VoxelState::kOccupied;
        if (occupied[i]) {
          box_lo = box_lo.cwiseMin(Eigen::Vector3i(kx, ky, kz));
          box_hi = box_hi.cwiseMax(Eigen::Vector3i(kx, ky, kz));
        }
        out.occupied += occupied[i];
        out.target += st == VoxelState::kTarget;
        out.free += st == VoxelState::kFree;
      }
    }
  // Node distances: to the nearest occupied node minus half a voxel outside, minus the distance to
  // the nearest free node plus half a voxel inside (the surface lies between the two node sets).
  const std::vector<float> to_occupied = squared_distance_transform(occupied, dims);
  const float half = static_cast<float>(0.5 * res), cap = 1.0f;
  std::vector<float> values(total);
  for (long i = 0; i < total; ++i) values[i] = std::min(std::sqrt(to_occupied[i]) * float(res) - half, cap);
  if (out.occupied > 0) inside_distances(occupied, dims, box_lo, box_hi, res, &values);
  out.obstacles =
      std::make_shared<geometry::SdfGrid>(geometry::SdfGrid::from_values(s.lo, res, dims, std::move(values)));

  // The target's observed surface: back-projected target pixels, normals from neighbouring pixels.
  std::vector<Eigen::Vector3d> pts, nrm;
  for (const DepthView& view : views) {
    if (view.target.size() == 0) continue;
    const double fx = view.K(0, 0), fy = view.K(1, 1), cx = view.K(0, 2), cy = view.K(1, 2);
    const long H = view.depth.rows(), W = view.depth.cols();
    auto point = [&](long r, long c, Eigen::Vector3d* w) {
      const float d = view.depth(r, c);
      if (!(std::isfinite(d) && d > 0)) return false;
      const double y = (r + 0.5 - cy) / fy * d, x = (c + 0.5 - cx) / fx * d;
      *w = view.camera_pose.R * Eigen::Vector3d(x, y, d) + view.camera_pose.p;
      return true;
    };
    for (long r = 0; r + 1 < H; r += s.target_stride)
      for (long c = 0; c + 1 < W; c += s.target_stride) {
        if (!view.target(r, c)) continue;
        Eigen::Vector3d p, pr, pd;
        if (!point(r, c, &p) || !point(r, c + 1, &pr) || !point(r + 1, c, &pd)) continue;
        if ((pr - p).norm() > 4 * res || (pd - p).norm() > 4 * res) continue;  // a depth edge, no normal
        Eigen::Vector3d n = (pr - p).cross(pd - p);
        if (n.norm() < 1e-12) continue;
        n.normalize();
        if (n.dot(view.camera_pose.p - p) < 0) n = -n;  // towards the camera: outward from the object
        pts.push_back(p);
        nrm.push_back(n);
      }
  }
  out.target_points.resize(static_cast<long>(pts.size()), 3);
  out.target_normals.resize(static_cast<long>(pts.size()), 3);
  for (std::size_t i = 0; i < pts.size(); ++i) {
    out.target_points.row(static_cast<long>(i)) = pts[i].transpose();
    out.target_normals.row(static_cast<long>(i)) = nrm[i].transpose();
  }
  return out;
}

}  // namespace pickplan::perception
