// SDF: batched queries with gradient on body points along a trajectory; grid build time.
#include <filesystem>
#include <random>

#include "bench_common.hpp"
#include "bench_meshes.hpp"
#include "pickplan/core/robot.hpp"
#include "pickplan/geometry/sdf.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace pickplan::bench {
namespace {

// Five objects (boxes and cylinders) on a table in front of the robot: the benchmark scene.
SceneSdf benchmark_scene(double resolution) {
  SceneSdf scene;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> ux(0.4, 0.7), uy(-0.3, 0.3), yaw(-M_PI, M_PI);
  for (int i = 0; i < 5; ++i) {
    Vertices V;
    Faces F;
    double half_h;
    if (i % 2 == 0) {
      box_mesh(0.06 + 0.02 * i, 0.1, 0.2, V, F);
      half_h = 0.1;
    } else {
      cylinder_mesh(0.035, 0.1 + 0.03 * i, 48, V, F);
      half_h = (0.1 + 0.03 * i) / 2;
    }
    auto grid = std::make_shared<SdfGrid>(SdfGrid::build(V, F, {resolution, 0.2}));
    Transform T;
    T.R = axis_angle(Eigen::Vector3d::UnitZ(), yaw(rng));
    T.p = Eigen::Vector3d(ux(rng), uy(rng), half_h);
    scene.add_object(grid, T);
  }
  Transform table;
  table.p = Eigen::Vector3d(0.45, 0, -0.05);
  scene.set_table(Eigen::Vector3d(1.3, 1.6, 0.1), table);
  return scene;
}

void bench_sdf(const Options& opt) {
  SceneSdf scene = benchmark_scene(0.005);
  Robot robot = Robot::from_urdf_file(opt.urdf);
  // Body points: 20 per link around each link frame, along a 30-step trajectory.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> off(-0.06, 0.06);
  RobotWorkspace ws(robot);
  const int T = 30, per_link = 20;
  std::vector<double> pts;
  Eigen::VectorXd q0 = Eigen::VectorXd::Zero(robot.dof()), q1 = Eigen::VectorXd::Zero(robot.dof());
  q0.head(7) << 0, -1.285, 0, -2.356, 0, 1.571, 0.785;
  q1.head(7) << 0.4, 0.3, 0.1, -2.0, 0.0, 2.2, 0.8;
  for (int t = 0; t < T; ++t) {
    Eigen::VectorXd q = q0 + (q1 - q0) * (t / double(T - 1));
    robot.forward_kinematics(q.data(), ws);
    for (int l = 0; l < robot.num_links(); ++l)
      for (int k = 0; k < per_link; ++k) {
        Eigen::Vector3d x = ws.link_pose[l].apply(Eigen::Vector3d(off(rng), off(rng), off(rng)));
        pts.insert(pts.end(), {x.x(), x.y(), x.z()});
      }
  }
  const long n = static_cast<long>(pts.size() / 3);
  std::vector<double> d(n), g(3 * n);
  const auto throughput = [&](const char* what, double cutoff) {
    Stats st = summarize(
        time_samples(opt.samples, 5, [&](int) { scene.distances(pts.data(), n, d.data(), g.data(), cutoff); }));
    char name[128];
    std::snprintf(name, sizeof name, "SDF+grad, %ld pts, %s", n, what);
    report(name, st);
    std::printf("    -> %.1f M points/s (median)%s\n", n / st.median / 1e6, cutoff < 1 ? "   [target >= 40 M/s]" : "");
  };
  throughput("per-object grids, cutoff 0.2", 0.2);
  throughput("per-object grids, no cutoff", 1e9);
  for (const MergedSdfSettings ms : {MergedSdfSettings{0.005, 0.2, 8}, MergedSdfSettings{}}) {
    char what[128];
    std::snprintf(what, sizeof what, "merged grid (%.0f mm, %d^3-voxel bricks)%s", ms.resolution * 1e3, ms.brick,
                  ms.resolution == MergedSdfSettings{}.resolution ? ", the default" : "");
    report((std::string(what) + ", build").c_str(), summarize(time_samples(3, 1, [&](int) { scene.merge(0, ms); })));
    std::printf("    -> %ld bricks, %.1f MB\n", scene.merged()->num_bricks(), scene.merged()->bytes() / 1e6);
    throughput(what, 0.2);
  }
  Vertices V;
  Faces F;
  cylinder_mesh(0.035, 0.1, 48, V, F);
  report("SDF build, cylinder (192 faces), 5 mm, margin 0.2",
         summarize(time_samples(3, 1, [&](int) { SdfGrid::build(V, F, {0.005, 0.2}); })));
  const std::string stl = opt.ycb_dir + "/006_mustard_bottle/mesh.stl";
  if (!opt.ycb_dir.empty() && std::filesystem::is_regular_file(stl)) {
    read_stl(stl, V, F);
    report("SDF build, YCB mustard bottle (15,728 faces), 5 mm",
           summarize(time_samples(3, 1, [&](int) { SdfGrid::build(V, F, {0.005, 0.2}); })));
  } else {
    std::printf("    (YCB SDF build skipped: pass --ycb DIR or set PICKPLAN_YCB_DIR)\n");
  }
}

Register reg("sdf", bench_sdf);

}  // namespace
}  // namespace pickplan::bench
