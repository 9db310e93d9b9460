#include "pickplan/omg/goal_set.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"
#include "pickplan/omg/metrics.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

// What build_goal_set returns: the goal set and its tails' shape (known without any goal).
struct GoalSetResult {
  GoalSet set;
  py::ssize_t tail_rows = 0, dof = 0;
};

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
      .def_readwrite("approach", &GoalSetSettings::approach)
      .def_readwrite("approach_substeps", &GoalSetSettings::approach_substeps);

  py::enum_<GoalReason> reason(m, "GoalReason", "Why an input grasp did or did not become a goal.");
  for (GoalReason r :
       {GoalReason::ok, GoalReason::unreachable, GoalReason::in_collision, GoalReason::standoff_unreachable,
        GoalReason::standoff_in_collision, GoalReason::approach_clearance, GoalReason::pregrasp_clearance,
        GoalReason::duplicate, GoalReason::over_cap})
    reason.value(to_string(r), r);

  result_class<GoalSetResult>(m, "GoalSetResult", "IK goals with their approach tails, per input grasp a reason.")
      .computed("goals", [](const GoalSetResult& r) -> const Trajectory& { return r.set.goals; })
      .computed("tails", [](const GoalSetResult& r) { return stacked_array(r.set.tails, r.tail_rows, r.dof); })
      .computed("grasp_index", [](const GoalSetResult& r) { return r.set.grasp_index; })
      .computed("reasons", [](const GoalSetResult& r) { return r.set.reasons; })
      .computed("seconds", [](const GoalSetResult& r) { return r.set.seconds; });

  m.def(
      "build_goal_set",
      [](const IkSolver& ik, const CollisionChecker* checker, const CollisionChecker* hand_checker,
         const Array& hand_poses, const Array& start, const GoalSetSettings& s, const ChompProblem* problem,
         double clearance, const py::object& seeds, double pregrasp_clearance) {
        std::vector<Transform> poses = poses_arg(hand_poses, "grasps");
        const Eigen::VectorXd qs = configuration_vector(ik.robot(), start, "start");
        Trajectory seed_rows;
        if (!seeds.is_none()) {
          seed_rows = configuration_rows(ik.robot(), seeds.cast<Array>(), "seeds", "B");
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
        return GoalSetResult{std::move(gs), s.standoff_steps + 1, ik.robot().dof()};
      },
      py::arg("ik"), py::arg("checker"), py::arg("hand_checker"), py::arg("hand_poses"), py::arg("start"),
      py::arg("settings") = GoalSetSettings(), py::arg("clearance_problem") = nullptr,
      py::arg("approach_clearance") = 0.0, py::arg("seeds") = py::none(), py::arg("pregrasp_clearance") = 0.0);
}

}  // namespace pickplan::bind
