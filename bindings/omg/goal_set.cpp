#include "../common.hpp"
#include "pickplan/omg/goal_set.hpp"
#include "pickplan/omg/metrics.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

py::array_t<double> traj_array(const Trajectory& t) {
  py::array_t<double> out({t.rows(), t.cols()});
  Eigen::Map<Trajectory>(out.mutable_data(), t.rows(), t.cols()) = t;
  return out;
}

}  // namespace

void init_goal_set(py::module_& m) {
  py::class_<GoalSetSettings>(m, "GoalSetSettings")
      .def(py::init<>())
      .def_readwrite("standoff", &GoalSetSettings::standoff)
      .def_readwrite("standoff_steps", &GoalSetSettings::standoff_steps)
      .def_readwrite("max_joint_jump", &GoalSetSettings::max_joint_jump)
      .def_readwrite("diversity", &GoalSetSettings::diversity)
      .def_readwrite("max_goals", &GoalSetSettings::max_goals)
      .def_readwrite("max_solutions", &GoalSetSettings::max_solutions)
      .def_readwrite("seed", &GoalSetSettings::seed)
      .def_readwrite("approach", &GoalSetSettings::approach);

  m.def("build_goal_set", [](const IkSolver& ik, const CollisionChecker* checker, const CollisionChecker* hand_checker,
                             const Array& hand_poses,
                             const Array& start, const GoalSetSettings& s, const ChompProblem* problem,
                             double clearance, const py::object& seeds, double pregrasp_clearance) {
    std::vector<Transform> poses = poses_arg(hand_poses, "grasps");
    Array q = configuration(ik.robot(), start, "start");
    Eigen::VectorXd qs = Eigen::Map<const Eigen::VectorXd>(q.data(), q.shape(0));
    Trajectory seed_rows;
    if (!seeds.is_none()) {
      Array Q = configurations(ik.robot(), seeds.cast<Array>(), "seeds");
      seed_rows = Eigen::Map<const Trajectory>(Q.data(), Q.shape(0), Q.shape(1));
      if (seed_rows.rows() != static_cast<long>(poses.size()))
        throw py::value_error("seeds: expected one configuration per grasp (" + std::to_string(poses.size()) +
                              "), got " + std::to_string(seed_rows.rows()));
    }
    GoalSet gs;
    {
      py::gil_scoped_release release;
      // The success test's approach clearance: body points to the objects the problem does not
      // exclude (the target), the table left out (metrics.cpp, object_clearance).
      RobotWorkspace rws(ik.robot());
      // A check that keeps `need` by that measure (none without a problem or a positive need); the
      // approach keeps `clearance`, the pre-grasp `pregrasp_clearance` (a place's pre-place: the transit's).
      auto keeps = [&](double need) -> std::function<bool(const Eigen::VectorXd&)> {
        if (!problem || !(need > 0)) return {};
        return [&, need](const Eigen::VectorXd& q) {
          return object_clearance(*problem, q.data(), problem->settings().exclude_mask, need, rws) >= need;
        };
      };
      const auto ok = keeps(clearance), pre = keeps(pregrasp_clearance);
      gs = build_goal_set(ik, checker, hand_checker, poses, qs, s, ok, seeds.is_none() ? nullptr : &seed_rows, pre);
    }
    py::dict d;
    d["goals"] = traj_array(gs.goals);
    const py::ssize_t G = gs.goals.rows(), m = s.standoff_steps + 1, dof = ik.robot().dof();
    py::array_t<double> tails({G, m, dof});
    for (py::ssize_t g = 0; g < G; ++g)
      Eigen::Map<Trajectory>(tails.mutable_data() + g * m * dof, m, dof) = gs.tails[g];
    d["tails"] = tails;
    d["grasp_index"] = gs.grasp_index;
    std::vector<std::string> reasons;  // their text forms: what plan files and Python read
    for (GoalReason r : gs.reasons) reasons.emplace_back(to_string(r));
    d["reasons"] = reasons;
    d["seconds"] = gs.seconds;
    return d;
  }, py::arg("ik"), py::arg("checker"), py::arg("hand_checker"), py::arg("hand_poses"), py::arg("start"),
     py::arg("settings") = GoalSetSettings(), py::arg("clearance_problem") = nullptr,
     py::arg("approach_clearance") = 0.0, py::arg("seeds") = py::none(), py::arg("pregrasp_clearance") = 0.0);
}

}  // namespace pickplan::bind
