// FCL collision: in_collision / min_distance per configuration for the Panda (link meshes read
// from the URDF's OBJ files by the native reader) among 5 seeded boxes and cylinders on a table.
#include <chrono>
#include <random>

#include "bench_common.hpp"
#include "pickplan/collision.hpp"

namespace pickplan::bench {
namespace {

std::vector<Eigen::VectorXd> random_configurations(const Robot& robot, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Eigen::VectorXd> qs;
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd q(robot.dof());
    for (int j = 0; j < robot.dof(); ++j) {
      double lo = std::isfinite(robot.lower_limits()[j]) ? robot.lower_limits()[j] : -M_PI;
      double hi = std::isfinite(robot.upper_limits()[j]) ? robot.upper_limits()[j] : M_PI;
      q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    qs.push_back(q);
  }
  return qs;
}

// Five objects standing on a table whose top is z = 0, in front of the robot (seeded).
std::vector<SceneObject> clutter(unsigned seed) {
  std::mt19937 rng(seed);
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  std::vector<SceneObject> out;
  for (int i = 0; i < 5; ++i) {
    SceneObject o;
    o.name = "obj" + std::to_string(i);
    double h;
    if (i % 2 == 0) {
      h = U(0.05, 0.22);
      o.mesh = TriangleMesh::box({U(0.04, 0.12), U(0.04, 0.12), h});
    } else {
      h = U(0.06, 0.22);
      o.mesh = TriangleMesh::cylinder(U(0.025, 0.05), h, 24);
    }
    o.pose.R = axis_angle(Eigen::Vector3d::UnitZ(), U(-M_PI, M_PI));
    o.pose.p = Eigen::Vector3d(U(0.35, 0.75), U(-0.35, 0.35), h / 2);
    out.push_back(std::move(o));
  }
  return out;
}

void bench_collision(const Options& opt) {
  Robot robot = Robot::from_urdf_file(opt.urdf);
  std::vector<LinkMesh> links;
  int faces = 0;
  for (int l = 0; l < robot.num_links(); ++l) {
    TriangleMesh m = link_collision_mesh(robot, l);
    if (m.num_faces() == 0) continue;
    faces += m.num_faces();
    links.push_back({robot.link(l).name, std::move(m)});
  }
  TableBox table{Eigen::Vector3d(1.1, 1.4, 0.05), Transform{}};
  table.pose.p = Eigen::Vector3d(0.75, 0, -0.025);
  const auto objects = clutter(0);
  auto t0 = std::chrono::steady_clock::now();
  CollisionChecker checker(robot, links, objects, table);
  auto t1 = std::chrono::steady_clock::now();
  std::printf("%zu links (%d faces), 5 objects + table, %d pairs; checker built in %.2f ms\n", links.size(), faces,
              checker.num_pairs(), std::chrono::duration<double>(t1 - t0).count() * 1e3);

  auto qs = random_configurations(robot, opt.samples * 5, 1);
  CollisionWorkspace ws(checker);
  std::vector<Eigen::VectorXd> free_qs, hit_qs;
  for (const auto& q : qs) (checker.in_collision(q.data(), ws) ? hit_qs : free_qs).push_back(q);
  std::printf("%zu configurations: %zu colliding, %zu free\n", qs.size(), hit_qs.size(), free_qs.size());
  int sink = 0;
  auto all = time_samples(static_cast<int>(qs.size()), 20, [&](int i) { sink += checker.in_collision(qs[i].data(), ws); });
  report("in_collision, random configurations", summarize(all));
  auto fr = time_samples(static_cast<int>(free_qs.size()), 20, [&](int i) { sink += checker.in_collision(free_qs[i].data(), ws); });
  report("in_collision, collision-free ones (no early exit)", summarize(fr));
  double dsink = 0;
  auto md = time_samples(static_cast<int>(free_qs.size()), 5, [&](int i) { dsink += checker.min_distance(free_qs[i].data(), ws); });
  report("min_distance, collision-free configurations", summarize(md));

  CollisionSettings self;
  self.self_collision = true;
  CollisionChecker with_self(robot, links, objects, table, self);
  CollisionWorkspace ws2(with_self);
  auto sc = time_samples(static_cast<int>(qs.size()), 20, [&](int i) { sink += with_self.in_collision(qs[i].data(), ws2); });
  report(("in_collision + self-collision (" + std::to_string(with_self.num_pairs()) + " pairs)").c_str(), summarize(sc));

  // Batch throughput on all cores.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Q(qs.size(), robot.dof());
  for (size_t i = 0; i < qs.size(); ++i) Q.row(static_cast<Eigen::Index>(i)) = qs[i].transpose();
  std::unique_ptr<bool[]> out(new bool[qs.size()]);
  for (int threads : {1, 2}) {
    auto b = time_samples(5, 1, [&](int) { checker.in_collision_batch(Q.data(), static_cast<long>(qs.size()), out.get(), threads); });
    Stats s = summarize(b);
    s.median /= qs.size(), s.worst /= qs.size(), s.mean /= qs.size();
    report(("in_collision_batch, " + std::to_string(threads) + " thread(s), per configuration").c_str(), s);
  }
  if (sink == -1 || dsink == -1) std::printf(" ");
}

Register reg("collision", bench_collision);

}  // namespace
}  // namespace pickplan::bench
