// [perception] the world model from depth images: one and three 640 x 480 views fused into the
// planner's signed distance field (space carving + exact distance transform), 1 cm voxels over the
// default workspace box. The images are ray-cast natively: a table plane with three boxes on it, seen
// from cameras 1.1 m from the work area's centre at 50 degrees elevation (the rig of sim/observe.py).
#include <cmath>

#include "bench_common.hpp"
#include "pickplan/perception/depth_field.hpp"

using namespace pickplan::perception;

namespace pickplan::bench {
namespace {

struct Box {
  Eigen::Vector3d lo, hi;
};

// Distance along the ray to the first hit of the table plane z = 0 or a box (slab test); 0 for none.
double cast(const Eigen::Vector3d& o, const Eigen::Vector3d& d, const std::vector<Box>& boxes) {
  double best = d.z() < -1e-9 ? -o.z() / d.z() : 0.0;
  for (const Box& b : boxes) {
    double t0 = 0, t1 = 1e9;
    for (int a = 0; a < 3; ++a) {
      if (std::abs(d[a]) < 1e-12) {
        if (o[a] < b.lo[a] || o[a] > b.hi[a]) t0 = 1e9;
        continue;
      }
      double u = (b.lo[a] - o[a]) / d[a], v = (b.hi[a] - o[a]) / d[a];
      if (u > v) std::swap(u, v);
      t0 = std::max(t0, u);
      t1 = std::min(t1, v);
    }
    if (t0 <= t1 && t0 > 0 && (best == 0 || t0 < best)) best = t0;
  }
  return best;
}

DepthView render(double azimuth, const std::vector<Box>& boxes) {
  const int W = 640, H = 480;
  const double fy = 0.5 * H / std::tan(58.0 * M_PI / 360.0);
  const Eigen::Vector3d target(0.55, 0, 0.05);
  const double e = 50.0 * M_PI / 180.0, a = azimuth * M_PI / 180.0;
  const Eigen::Vector3d eye =
      target + 1.1 * Eigen::Vector3d(std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e));
  const Eigen::Vector3d z = (target - eye).normalized(), x = z.cross(Eigen::Vector3d::UnitZ()).normalized(),
                        y = z.cross(x);
  DepthView v;
  v.K << fy, 0, W / 2.0, 0, fy, H / 2.0, 0, 0, 1;
  v.camera_pose.R << x, y, z;
  v.camera_pose.p = eye;
  v.depth.resize(H, W);
  v.target = PixelMask::Zero(H, W);
  for (int r = 0; r < H; ++r)
    for (int c = 0; c < W; ++c) {
      const Eigen::Vector3d ray_cam((c + 0.5 - W / 2.0) / fy, (r + 0.5 - H / 2.0) / fy, 1.0);
      const double t = cast(eye, v.camera_pose.R * ray_cam, boxes);  // t along a ray with unit z: depth
      v.depth(r, c) = static_cast<float>(t);
      const Eigen::Vector3d hit = eye + t * (v.camera_pose.R * ray_cam);
      v.target(r, c) =
          t > 0 && hit.z() > 0.002 && (hit - boxes[0].lo).minCoeff() > -1e-6 && (boxes[0].hi - hit).minCoeff() > -1e-6;
    }
  return v;
}

void bench_perception(const Options& opt) {
  const std::vector<Box> boxes = {{{0.5, -0.04, 0}, {0.56, 0.04, 0.18}},
                                  {{0.6, 0.15, 0}, {0.68, 0.22, 0.1}},
                                  {{0.4, -0.25, 0}, {0.47, -0.15, 0.07}}};
  const std::vector<DepthView> views = {render(0, boxes), render(70, boxes), render(-70, boxes)};
  DepthFieldSettings s;
  s.has_plane = true;
  const int samples = std::max(5, opt.samples / 20);
  for (int n : {1, 3}) {
    std::vector<DepthView> use(views.begin(), views.begin() + n);
    DepthField f;
    auto t = time_samples(samples, 1, [&](int) { f = build_depth_field(use, s); });
    const std::string name = "depth field, " + std::to_string(n) + " view(s) 640 x 480, 1 cm";
    report(name.c_str(), summarize(t), n == 1 ? "[target <= 50 ms]" : "[target <= 100 ms]");
    std::printf("    -> %d occupied, %d target, %d free voxels; %ld target points\n", f.occupied, f.target, f.free,
                static_cast<long>(f.target_points.rows()));
  }
}

Register reg("perception", bench_perception);

}  // namespace
}  // namespace pickplan::bench
