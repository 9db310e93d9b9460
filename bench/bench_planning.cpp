// Planning core: one CHOMP iteration, a 100-iteration optimization, goal-cost estimates,
// one IK solve and a 100-grasp goal set, on a fixed seeded 5-object clutter scene.
#include <chrono>
#include <map>
#include <random>

#include "bench_common.hpp"
#include "pickplan/core/ik.hpp"
#include "pickplan/geometry/collision.hpp"
#include "pickplan/geometry/mesh.hpp"
#include "pickplan/omg/chomp.hpp"
#include "pickplan/omg/goal_set.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bench {
namespace {

struct Clutter {
  std::vector<SceneObject> objects;
  TableBox table;
  std::shared_ptr<SceneSdf> sdf;
};

Clutter make_clutter(unsigned seed) {
  std::mt19937 rng(seed);
  auto U = [&](double a, double b) { return std::uniform_real_distribution<double>(a, b)(rng); };
  Clutter c;
  c.sdf = std::make_shared<SceneSdf>();
  for (int i = 0; i < 5; ++i) {
    SceneObject o;
    o.name = "obj" + std::to_string(i);
    const double h = U(0.08, 0.22);
    o.mesh =
        i % 2 == 0 ? TriangleMesh::box({U(0.05, 0.1), U(0.05, 0.1), h}) : TriangleMesh::cylinder(U(0.03, 0.045), h, 32);
    o.pose.R = axis_angle(Eigen::Vector3d::UnitZ(), U(-M_PI, M_PI));
    o.pose.p = Eigen::Vector3d(U(0.4, 0.7), U(-0.3, 0.3), h / 2);
    c.sdf->add_object(std::make_shared<SdfGrid>(SdfGrid::build(o.mesh.vertices, o.mesh.faces, {0.005, 0.2})), o.pose);
    c.objects.push_back(std::move(o));
  }
  c.table.size = Eigen::Vector3d(1.3, 1.6, 0.05);
  c.table.pose.p = Eigen::Vector3d(0.45, 0, -0.025);
  c.sdf->set_table(c.table.size, c.table.pose);
  return c;
}

// 20 points per moving link, on its collision mesh (random triangle, random barycentric).
BodyPoints body_points(const Robot& robot, int per_link, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  BodyPoints body;
  std::vector<Eigen::Vector3d> pts;
  for (int l = 1; l < robot.num_links(); ++l) {
    TriangleMesh m = link_collision_mesh(robot, l);
    if (m.num_faces() == 0) continue;
    for (int k = 0; k < per_link; ++k) {
      const int f = std::uniform_int_distribution<int>(0, m.num_faces() - 1)(rng);
      double a = u(rng), b = u(rng);
      if (a + b > 1) a = 1 - a, b = 1 - b;
      pts.push_back(m.vertices.row(m.faces(f, 0)) * (1 - a - b) + m.vertices.row(m.faces(f, 1)) * a +
                    m.vertices.row(m.faces(f, 2)) * b);
      body.link.push_back(l);
    }
  }
  body.points.resize(pts.size(), 3);
  for (size_t i = 0; i < pts.size(); ++i) body.points.row(i) = pts[i];
  return body;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void bench_planning(const Options& opt) {
  auto robot = std::make_shared<Robot>(Robot::from_urdf_file(opt.urdf));
  const Clutter clutter = make_clutter(3);
  ChompSettings cs;
  cs.active = std::vector<bool>(robot->dof(), true);
  cs.active[7] = cs.active[8] = false;
  ChompProblem chomp(robot, clutter.sdf, body_points(*robot, 20, 0), cs);
  std::printf("%d body points, n = %d, 5 objects + table\n", chomp.body().size(), cs.n);
  Eigen::VectorXd q0(9), g(9);
  q0 << 0, -1.285, 0, -2.356, 0, 1.571, 0.785, 0.04, 0.04;
  g << -0.35, 0.55, -0.1, -1.9, 0.05, 2.45, 0.4, 0.04, 0.04;
  Trajectory xi0(cs.n, 9), goal = g.transpose();
  for (int t = 0; t < cs.n; ++t) {
    const double s = (t + 1.0) / cs.n, b = 3 * s * s - 2 * s * s * s;
    xi0.row(t) = (q0 + b * (g - q0)).transpose();
  }
  ChompWorkspace ws(chomp);
  Trajectory xi = xi0;
  int it = 0;
  report("CHOMP-Proj iteration, per-object grids",
         summarize(time_samples(opt.samples, 1, [&](int) { chomp.step(xi, q0, &goal, it++, ws); })));
  const auto t_merge = std::chrono::steady_clock::now();
  clutter.sdf->merge(cs.exclude_mask, MergedSdfSettings{});
  std::printf("merged scene grid built in %.1f ms\n", 1e3 * seconds_since(t_merge));
  xi = xi0;
  it = 0;
  report("CHOMP-Proj iteration (n=30, 20 pts/link)",
         summarize(time_samples(opt.samples, 1, [&](int) { chomp.step(xi, q0, &goal, it++, ws); })),
         "[target <= 100 us]");
  report("CHOMP, 100 iterations", summarize(time_samples(5, 1, [&](int) { chomp.optimize(xi0, q0, goal, 100); })));
  Trajectory goals(30, 9);
  std::mt19937 rng(5);
  for (int k = 0; k < 30; ++k)
    goals.row(k) = (g + 0.3 * Eigen::VectorXd::Random(9).cwiseProduct(Eigen::VectorXd::Ones(9))).transpose();
  goals.col(7).setConstant(0.04);
  goals.col(8).setConstant(0.04);
  std::vector<double> costs(30);
  for (int stride : {1, 2}) {
    char name[96];
    std::snprintf(name, sizeof name, "goal costs, 30 goals, stride %d x %d", stride, stride);
    report(name, summarize(time_samples(opt.samples / 4 + 1, 1, [&](int i) {
             chomp.goal_costs(xi, q0, i % 50, 50, goals, stride, stride, costs.data(), ws);
           })));
  }

  // IK and goal sets.
  IkSettings iks;
  for (bool a : cs.active) iks.weights.push_back(a ? 1.0 : 0.0);
  IkSolver ik(robot, robot->link_index("panda_hand"), iks);
  RobotWorkspace rws(*robot);
  std::vector<Transform> targets;
  std::uniform_real_distribution<double> u(0.2, 0.8);
  for (int k = 0; k < opt.samples; ++k) {
    Eigen::VectorXd q(9);
    for (int j = 0; j < 9; ++j)
      q[j] = robot->lower_limits()[j] + u(rng) * (robot->upper_limits()[j] - robot->lower_limits()[j]);
    robot->forward_kinematics(q.data(), rws);
    targets.push_back(rws.link_pose[robot->link_index("panda_hand")]);
  }
  report("IK, one solve from the start (random reachable pose)",
         summarize(time_samples(opt.samples, 1, [&](int i) { ik.solve(targets[i], q0); })));
  report("IK, first solution over all seeds",
         summarize(time_samples(opt.samples, 1, [&](int i) { ik.solve_any(targets[i], q0); })));
  std::vector<LinkMesh> links;
  for (int l = 0; l < robot->num_links(); ++l) {
    TriangleMesh m = link_collision_mesh(*robot, l);
    if (m.num_faces() > 0) links.push_back({robot->link(l).name, std::move(m)});
  }
  CollisionSettings col;
  col.allowed_pairs = {{"panda_link0", "table"}, {"panda_leftfinger", "obj1"}, {"panda_rightfinger", "obj1"}};
  CollisionChecker checker(*robot, links, clutter.objects, clutter.table, col);
  std::vector<LinkMesh> hand_links;
  for (const auto& lm : links)
    if (lm.link == "panda_hand" || lm.link == "panda_leftfinger" || lm.link == "panda_rightfinger")
      hand_links.push_back(lm);
  CollisionChecker hand_checker(*robot, hand_links, clutter.objects, clutter.table, col);
  // 100 side grasps around the target cylinder obj1 (ring of approach directions, 4 heights).
  std::vector<Transform> grasps;
  const Transform& target = clutter.objects[1].pose;
  for (int k = 0; k < 100; ++k) {
    const double a = 2 * M_PI * (k % 25) / 25, z = -0.03 + 0.02 * (k / 25);
    Eigen::Vector3d zz(-std::cos(a), -std::sin(a), 0), yy(-std::sin(a), std::cos(a), 0);
    Transform T;
    T.R.col(0) = yy.cross(zz);
    T.R.col(1) = yy;
    T.R.col(2) = zz;
    T.p = target.p + Eigen::Vector3d(0, 0, z) - 0.105 * zz;
    grasps.push_back(T);
  }
  GoalSet gs;
  report("goal set, 100 grasps, standoff, clutter",
         summarize(time_samples(5, 1, [&](int) { gs = build_goal_set(ik, &checker, &hand_checker, grasps, q0, {}); })),
         "[target <= 50 ms]");
  std::map<std::string, int> reasons;
  for (const auto& r : gs.reasons) ++reasons[to_string(r)];
  std::printf("    -> %zu goals after the cap; grasps by outcome:", static_cast<size_t>(gs.goals.rows()));
  for (const auto& [r, count] : reasons) std::printf(" %s %d", r.c_str(), count);
  std::printf("\n");
}

Register reg("planning", bench_planning);

}  // namespace
}  // namespace pickplan::bench
