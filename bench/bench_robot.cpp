// Kinematics: FK of all links, and FK plus the Jacobians of every link, per configuration.
#include <random>

#include "bench_common.hpp"
#include "pickplan/core/robot.hpp"

using namespace pickplan::core;

namespace pickplan::bench {
namespace {

void bench_kinematics(const Options& opt) {
  Robot robot = Robot::from_urdf_file(opt.urdf);
  auto qs = random_configurations(robot, opt.samples * 5, 0);
  RobotWorkspace ws(robot);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, robot.dof());
  double sink = 0;
  const int n = static_cast<int>(qs.size());
  auto fk = time_samples(n, 200, [&](int i) {
    robot.forward_kinematics(qs[i].data(), ws);
    sink += ws.link_pose.back().p.x();
  });
  report(("FK, all " + std::to_string(robot.num_links()) + " links (per configuration)").c_str(), summarize(fk));
  auto fkj = time_samples(n, 200, [&](int i) {
    robot.forward_kinematics(qs[i].data(), ws);
    for (int l = 0; l < robot.num_links(); ++l) {
      robot.point_jacobian(ws, l, Eigen::Vector3d::Zero(), J);
      sink += J(0, 0);
    }
  });
  report("FK + 6xdof Jacobians of all links (per config)", summarize(fkj), "[target <= 1 us]");
  if (sink == 42.0) std::printf(" ");
}

Register reg("kinematics", bench_kinematics);

}  // namespace
}  // namespace pickplan::bench
