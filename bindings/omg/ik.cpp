#include "../common.hpp"
#include "pickplan/omg/goal_set.hpp"
#include "pickplan/core/ik.hpp"
#include "pickplan/omg/metrics.hpp"

namespace pickplan::bind {

namespace {

Transform pose_arg(const Array& T, const char* what) { return Transform::from_matrix(matrix4(T, what)); }

std::vector<Transform> poses_arg(const Array& P, const char* what) {
  require_shape(what, P, {-1, 4, 4}, "(N, 4, 4)");
  require_finite_array(what, P);
  std::vector<Transform> out;
  for (py::ssize_t i = 0; i < P.shape(0); ++i) {
    Eigen::Matrix4d M = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(P.data() + 16 * i);
    out.push_back(Transform::from_matrix(cleaned_rigid((std::string(what) + " [" + std::to_string(i) + "]").c_str(), M)));
  }
  return out;
}

py::dict solution_dict(const IkSolution& s) {
  py::dict d;
  d["q"] = s.q;
  d["converged"] = s.converged;
  d["position_error"] = s.position_error;
  d["rotation_error"] = s.rotation_error;
  d["iterations"] = s.iterations;
  return d;
}

py::array_t<double> traj_array(const Trajectory& t) {
  py::array_t<double> out({t.rows(), t.cols()});
  Eigen::Map<Trajectory>(out.mutable_data(), t.rows(), t.cols()) = t;
  return out;
}

}  // namespace

void init_ik(py::module_& m) {
  py::class_<IkSettings>(m, "IkSettings")
      .def(py::init<>())
      .def_readwrite("max_iterations", &IkSettings::max_iterations)
      .def_readwrite("position_tolerance", &IkSettings::position_tolerance)
      .def_readwrite("rotation_tolerance", &IkSettings::rotation_tolerance)
      .def_readwrite("damping", &IkSettings::damping)
      .def_readwrite("max_step", &IkSettings::max_step)
      .def_readwrite("num_seeds", &IkSettings::num_seeds)
      .def_readwrite("seed", &IkSettings::seed)
      .def_readwrite("duplicate_tolerance", &IkSettings::duplicate_tolerance)
      .def_readwrite("active", &IkSettings::active);

  py::class_<GoalSetSettings>(m, "GoalSetSettings")
      .def(py::init<>())
      .def_readwrite("standoff", &GoalSetSettings::standoff)
      .def_readwrite("standoff_steps", &GoalSetSettings::standoff_steps)
      .def_readwrite("max_joint_jump", &GoalSetSettings::max_joint_jump)
      .def_readwrite("diversity", &GoalSetSettings::diversity)
      .def_readwrite("max_goals", &GoalSetSettings::max_goals)
      .def_readwrite("max_solutions", &GoalSetSettings::max_solutions)
      .def_readwrite("seed", &GoalSetSettings::seed);

  py::class_<IkSolver, std::shared_ptr<IkSolver>>(m, "IkSolver")
      .def(py::init([](std::shared_ptr<Robot> robot, const py::object& link, const IkSettings& s) {
             return std::make_shared<IkSolver>(robot, link_arg(*robot, link), s);
           }),
           py::arg("robot"), py::arg("link"), py::arg("settings") = IkSettings())
      .def("solve", [](const IkSolver& ik, const Array& T, const Array& seed) {
        Transform target = pose_arg(T, "target pose");
        Array q = configuration(ik.robot(), seed, "seed");
        Eigen::VectorXd qs = Eigen::Map<const Eigen::VectorXd>(q.data(), q.shape(0));
        IkSolution s;
        {
          py::gil_scoped_release release;
          s = ik.solve(target, qs);
        }
        return solution_dict(s);
      }, py::arg("target"), py::arg("seed"))
      .def("solve_all", [](const IkSolver& ik, const Array& T, const Array& start) {
        Transform target = pose_arg(T, "target pose");
        Array q = configuration(ik.robot(), start, "start");
        Eigen::VectorXd qs = Eigen::Map<const Eigen::VectorXd>(q.data(), q.shape(0));
        std::vector<IkSolution> sols;
        {
          py::gil_scoped_release release;
          sols = ik.solve_all(target, qs);
        }
        py::list out;
        for (const auto& s : sols) out.append(solution_dict(s));
        return out;
      }, py::arg("target"), py::arg("start"), "Every distinct converged solution, nearest to start first.")
      .def("solve_batch", [](const IkSolver& ik, const Array& P, const Array& start) {
        std::vector<Transform> targets = poses_arg(P, "target poses");
        Array q = configuration(ik.robot(), start, "start");
        Eigen::VectorXd qs = Eigen::Map<const Eigen::VectorXd>(q.data(), q.shape(0));
        const py::ssize_t n = static_cast<py::ssize_t>(targets.size());
        py::array_t<double> Q({n, static_cast<py::ssize_t>(ik.robot().dof())});
        py::array_t<bool> ok(n);
        double* qp = Q.mutable_data();
        bool* okp = ok.mutable_data();
        {
          py::gil_scoped_release release;
          for (py::ssize_t i = 0; i < n; ++i) {
            IkSolution s = ik.solve_any(targets[i], qs);
            Eigen::Map<Eigen::VectorXd>(qp + i * ik.robot().dof(), ik.robot().dof()) = s.q;
            okp[i] = s.converged;
          }
        }
        return py::make_tuple(Q, ok);
      }, py::arg("targets"), py::arg("start"), "First converged solution per pose: (Q (N, dof), converged (N,)).");

  m.def("build_goal_set", [](const IkSolver& ik, const CollisionChecker* checker, const CollisionChecker* hand_checker,
                             const Array& hand_poses,
                             const Array& start, const GoalSetSettings& s, const ChompProblem* problem,
                             double clearance) {
    std::vector<Transform> poses = poses_arg(hand_poses, "grasps");
    Array q = configuration(ik.robot(), start, "start");
    Eigen::VectorXd qs = Eigen::Map<const Eigen::VectorXd>(q.data(), q.shape(0));
    GoalSet gs;
    {
      py::gil_scoped_release release;
      // The success test's approach clearance: body points to the objects the problem does not
      // exclude (the target), the table left out (metrics.cpp, object_clearance).
      RobotWorkspace rws(ik.robot());
      std::function<bool(const Eigen::VectorXd&)> ok;
      if (problem && clearance > 0)
        ok = [&](const Eigen::VectorXd& q) {
          return object_clearance(*problem, q.data(), problem->settings().exclude_mask, clearance, rws) >= clearance;
        };
      gs = build_goal_set(ik, checker, hand_checker, poses, qs, s, ok);
    }
    py::dict d;
    d["goals"] = traj_array(gs.goals);
    const py::ssize_t G = gs.goals.rows(), m = s.standoff_steps + 1, dof = ik.robot().dof();
    py::array_t<double> tails({G, m, dof});
    for (py::ssize_t g = 0; g < G; ++g)
      Eigen::Map<Trajectory>(tails.mutable_data() + g * m * dof, m, dof) = gs.tails[g];
    d["tails"] = tails;
    d["grasp_index"] = gs.grasp_index;
    d["reasons"] = gs.reasons;
    d["seconds"] = gs.seconds;
    return d;
  }, py::arg("ik"), py::arg("checker"), py::arg("hand_checker"), py::arg("hand_poses"), py::arg("start"),
     py::arg("settings") = GoalSetSettings(), py::arg("clearance_problem") = nullptr,
     py::arg("approach_clearance") = 0.0);
}

}  // namespace pickplan::bind
