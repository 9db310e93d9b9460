// The damped-least-squares IK (core/ik.hpp): settings, enums and the multi-start solver.
#include "pickplan/core/ik.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"

using namespace pickplan::core;

namespace pickplan::bind {

namespace {

// Solutions as arrays: (Q (N, dof), converged (N,)).
py::tuple solution_arrays(const std::vector<IkSolution>& sols, int dof) {
  Rows Q(sols.size(), dof);
  std::vector<bool> ok;
  for (std::size_t i = 0; i < sols.size(); ++i) {
    Q.row(static_cast<long>(i)) = sols[i].q.transpose();
    ok.push_back(sols[i].converged);
  }
  return py::make_tuple(rows_array(Q), mask_array(ok));
}

}  // namespace

void init_ik(py::module_& m) {
  py::enum_<IkTask>(m, "IkTask").value("pose", IkTask::pose).value("position", IkTask::position);
  py::enum_<IkDamping>(m, "IkDamping").value("adaptive", IkDamping::adaptive).value("fixed", IkDamping::fixed);
  py::enum_<IkStepNorm>(m, "IkStepNorm")
      .value("max_abs", IkStepNorm::max_abs)
      .value("euclidean", IkStepNorm::euclidean);

  py::enum_<IkRotationError>(m, "IkRotationError")
      .value("angle_axis", IkRotationError::angle_axis)
      .value("sine_axis", IkRotationError::sine_axis);

  py::class_<DlsSettings>(m, "DlsSettings")
      .def(py::init<>())
      .def_readwrite("task", &DlsSettings::task)
      .def_readwrite("rotation_error", &DlsSettings::rotation_error)
      .def_readwrite("max_iterations", &DlsSettings::max_iterations)
      .def_readwrite("position_tolerance", &DlsSettings::position_tolerance)
      .def_readwrite("rotation_tolerance", &DlsSettings::rotation_tolerance)
      .def_readwrite("damping_schedule", &DlsSettings::damping_schedule)
      .def_readwrite("damping", &DlsSettings::damping)
      .def_readwrite("damping_decrease", &DlsSettings::damping_decrease)
      .def_readwrite("damping_increase", &DlsSettings::damping_increase)
      .def_readwrite("min_damping", &DlsSettings::min_damping)
      .def_readwrite("max_damping", &DlsSettings::max_damping)
      .def_readwrite("min_relative_decrease", &DlsSettings::min_relative_decrease)
      .def_readwrite("max_stalled_iterations", &DlsSettings::max_stalled_iterations)
      .def_readwrite("max_step", &DlsSettings::max_step)
      .def_readwrite("step_norm", &DlsSettings::step_norm)
      .def_readwrite("limit_margin", &DlsSettings::limit_margin)
      .def_readwrite("weights", &DlsSettings::weights);

  result_class<IkSolution>(m, "IkSolution", "One IK descent's end: q, whether it converged, its errors.")
      .field("q", &IkSolution::q)
      .field("converged", &IkSolution::converged)
      .field("position_error", &IkSolution::position_error)
      .field("rotation_error", &IkSolution::rotation_error)
      .field("iterations", &IkSolution::iterations);

  py::class_<IkSettings, DlsSettings>(m, "IkSettings")
      .def(py::init<>())
      .def_readwrite("num_seeds", &IkSettings::num_seeds)
      .def_readwrite("seed", &IkSettings::seed)
      .def_readwrite("duplicate_tolerance", &IkSettings::duplicate_tolerance);

  py::class_<IkSolver, std::shared_ptr<IkSolver>>(m, "IkSolver")
      .def(py::init([](std::shared_ptr<Robot> robot, const py::object& link, const IkSettings& s) {
             return std::make_shared<IkSolver>(robot, link_arg(*robot, link), s);
           }),
           py::arg("robot"), py::arg("link"), py::arg("settings") = IkSettings())
      .def(
          "solve",
          [](const IkSolver& ik, const Array& T, const Array& seed) {
            const Transform target = pose_arg(T, "target pose");
            const Eigen::VectorXd qs = configuration_vector(ik.robot(), seed, "seed");
            IkSolution s;
            {
              py::gil_scoped_release release;
              s = ik.solve(target, qs);
            }
            return s;
          },
          py::arg("target"), py::arg("seed"), "One descent from seed: an IkSolution.")
      .def(
          "solve_path",
          [](const IkSolver& ik, const Array& P, const Array& seed) {
            const std::vector<Transform> targets = poses_arg(P, "target poses");
            const Eigen::VectorXd qs = configuration_vector(ik.robot(), seed, "seed");
            std::vector<IkSolution> sols;
            {
              py::gil_scoped_release release;
              sols = ik.solve_path(targets, qs);
            }
            return solution_arrays(sols, ik.robot().dof());
          },
          py::arg("targets"), py::arg("seed"),
          "One descent per pose, each from the previous solution: (Q (N, dof), converged (N,)).")
      .def(
          "solve_all",
          [](const IkSolver& ik, const Array& T, const Array& start) {
            const Transform target = pose_arg(T, "target pose");
            const Eigen::VectorXd qs = configuration_vector(ik.robot(), start, "start");
            std::vector<IkSolution> sols;
            {
              py::gil_scoped_release release;
              sols = ik.solve_all(target, qs);
            }
            return sols;
          },
          py::arg("target"), py::arg("start"),
          "Every distinct converged solution (IkSolution), nearest to start first.")
      .def(
          "solve_batch",
          [](const IkSolver& ik, const Array& P, const Array& start) {
            const std::vector<Transform> targets = poses_arg(P, "target poses");
            const Eigen::VectorXd qs = configuration_vector(ik.robot(), start, "start");
            std::vector<IkSolution> sols(targets.size());
            {
              py::gil_scoped_release release;
              for (std::size_t i = 0; i < targets.size(); ++i) sols[i] = ik.solve_any(targets[i], qs);
            }
            return solution_arrays(sols, ik.robot().dof());
          },
          py::arg("targets"), py::arg("start"), "First converged solution per pose: (Q (N, dof), converged (N,)).");
}

}  // namespace pickplan::bind
