// FCL collision: in_collision / min_distance per configuration for the Panda (link meshes read
// from the URDF's OBJ files by the native reader) among 5 seeded boxes and cylinders on a table.
#include <chrono>
#include <cmath>
#include <memory>
#include <random>

#include "bench_common.hpp"
#include "pickplan/geometry/collision.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace pickplan::bench {
namespace {

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

  // Two fixed sets: uniform within the joint limits, and reaching into the clutter (hand
  // inside x 0.25..0.85, |y| < 0.45, z -0.05..0.3; rejection-sampled), where contacts happen.
  const int n = opt.samples * 5;
  auto qs = random_configurations(robot, n, 1);
  std::vector<Eigen::VectorXd> reach;
  {
    RobotWorkspace rws(robot);
    const int hand = robot.link_index("panda_hand");
    for (const auto& q : random_configurations(robot, 40 * n, 2)) {
      robot.forward_kinematics(q.data(), rws);
      const Eigen::Vector3d p = rws.link_pose[hand].p;
      if (p.x() > 0.25 && p.x() < 0.85 && std::abs(p.y()) < 0.45 && p.z() > -0.05 && p.z() < 0.3) reach.push_back(q);
      if (static_cast<int>(reach.size()) == n) break;
    }
  }
  CollisionWorkspace ws(checker);
  int sink = 0;
  double dsink = 0;
  for (const auto* set : {&qs, &reach}) {
    const char* tag = set == &qs ? "uniform" : "reaching";
    std::vector<Eigen::VectorXd> free_qs;
    for (const auto& q : *set)
      if (!checker.in_collision(q.data(), ws)) free_qs.push_back(q);
    std::printf("%s: %zu configurations, %zu colliding\n", tag, set->size(), set->size() - free_qs.size());
    auto all = time_samples(static_cast<int>(set->size()), 20,
                            [&](int i) { sink += checker.in_collision((*set)[i].data(), ws); });
    report((std::string("in_collision, ") + tag).c_str(), summarize(all));
    auto fr = time_samples(static_cast<int>(free_qs.size()), 20,
                           [&](int i) { sink += checker.in_collision(free_qs[i].data(), ws); });
    report((std::string("in_collision, ") + tag + ", free ones (no early exit)").c_str(), summarize(fr));
    auto md = time_samples(static_cast<int>(free_qs.size()), 3,
                           [&](int i) { dsink += checker.min_distance(free_qs[i].data(), ws); });
    report((std::string("min_distance, ") + tag + ", free ones").c_str(), summarize(md));
  }

  CollisionSettings self;
  self.self_collision = true;
  CollisionChecker with_self(robot, links, objects, table, self);
  CollisionWorkspace ws2(with_self);
  auto sc = time_samples(static_cast<int>(reach.size()), 20,
                         [&](int i) { sink += with_self.in_collision(reach[i].data(), ws2); });
  report(("in_collision + self-collision, reaching (" + std::to_string(with_self.num_pairs()) + " pairs)").c_str(),
         summarize(sc));

  // Batch throughput (reaching set) on 1 and 2 threads.
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Q(reach.size(), robot.dof());
  for (size_t i = 0; i < reach.size(); ++i) Q.row(static_cast<Eigen::Index>(i)) = reach[i].transpose();
  std::unique_ptr<bool[]> out(new bool[reach.size()]);
  for (int threads : {1, 2}) {
    auto b = time_samples(
        5, 1, [&](int) { checker.in_collision_batch(Q.data(), static_cast<long>(reach.size()), out.get(), threads); });
    Stats s = summarize(b);
    s.median /= reach.size(), s.worst /= reach.size(), s.mean /= reach.size();
    report(("in_collision_batch, " + std::to_string(threads) + " thread(s), per configuration").c_str(), s);
  }
  if (sink == -1 || dsink == -1) std::printf(" ");
}

Register reg("collision", bench_collision);

}  // namespace
}  // namespace pickplan::bench
