// Bindings of RRT-Connect and the motion check (pickplan/omg/rrt_connect.hpp).
#include "pickplan/omg/rrt_connect.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

Trajectory path_arg(const MotionPlanner& p, const Array& a, const char* what) {
  return configuration_rows(p.checker().robot(), a, what, "k");
}

}  // namespace

void init_rrt_connect(py::module_& m) {
  py::enum_<RrtStatus>(m, "RrtStatus")
      .value("solved", RrtStatus::solved)
      .value("timeout", RrtStatus::timeout)
      .value("iterations", RrtStatus::iterations)
      .value("invalid_start", RrtStatus::invalid_start)
      .value("invalid_goals", RrtStatus::invalid_goals);
  result_class<RrtResult>(m, "RrtResult", "RRT-Connect's path (start ... goal rows, when solved) and its effort.")
      .field("status", &RrtResult::status)
      .field("path", &RrtResult::path)
      .field("goal", &RrtResult::goal)
      .field("iterations", &RrtResult::iterations)
      .field("checks", &RrtResult::checks)
      .field("nodes", &RrtResult::nodes)
      .field("seconds", &RrtResult::seconds);
  py::class_<RrtSettings>(m, "RrtSettings")
      .def(py::init<>())
      .def_readwrite("range", &RrtSettings::range)
      .def_readwrite("resolution", &RrtSettings::resolution)
      .def_readwrite("max_iterations", &RrtSettings::max_iterations)
      .def_readwrite("time_limit", &RrtSettings::time_limit)
      .def_readwrite("seed", &RrtSettings::seed)
      .def_readwrite("goal_bias", &RrtSettings::goal_bias)
      .def_readwrite("certified", &RrtSettings::certified)
      .def_readwrite("active", &RrtSettings::active);
  py::class_<MotionPlanner>(m, "MotionPlanner", "RRT-Connect, shortcutting and the motion check on an FCL checker.")
      .def(py::init<const CollisionChecker&, RrtSettings>(), py::arg("checker"), py::arg("settings") = RrtSettings{},
           py::keep_alive<1, 2>())
      .def_property_readonly("motion_factors", [](const MotionPlanner& p) { return p.bound().factors(); })
      .def(
          "rrt_connect",
          [](const MotionPlanner& p, const Array& start, const Array& goals) {
            const Eigen::VectorXd q0 = configuration_vector(p.checker().robot(), start, "start");
            const Trajectory G = path_arg(p, goals, "goals");
            RrtResult r;
            {
              py::gil_scoped_release release;
              r = p.rrt_connect(q0, G);
            }
            return r;
          },
          py::arg("start"), py::arg("goals"), "RRT-Connect from start to any row of goals: an RrtResult.")
      .def(
          "shortcut",
          [](const MotionPlanner& p, const Array& path, int attempts, std::uint64_t seed, double min_gain) {
            const Trajectory P = path_arg(p, path, "path");
            if (attempts < 0) throw std::invalid_argument("attempts: expected >= 0");
            if (!(min_gain >= 0.0 && min_gain < 1.0))
              throw std::invalid_argument("min_gain: expected a fraction in [0, 1)");
            py::gil_scoped_release release;
            return p.shortcut(P, attempts, seed, min_gain);
          },
          py::arg("path"), py::arg("attempts") = 100, py::arg("seed") = 0, py::arg("min_gain") = 0.0,
          "Random shortcuts, each shortening the path by at least min_gain of its length, then vertices dropped.")
      .def(
          "first_invalid_segment",
          [](const MotionPlanner& p, const Array& path) {
            const Trajectory P = path_arg(p, path, "path");
            py::gil_scoped_release release;
            return p.first_invalid_segment(P);
          },
          py::arg("path"), "The first segment (row i -> i + 1) failing the motion check, or -1.");
}

}  // namespace pickplan::bind
