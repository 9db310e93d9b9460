// The damped-least-squares IK (core/ik.hpp): settings, enums and the multi-start solver.
#include "../common.hpp"
#include "pickplan/core/ik.hpp"

using namespace pickplan::core;

namespace pickplan::bind {

namespace {

py::dict solution_dict(const IkSolution& s) {
  py::dict d;
  d["q"] = s.q;
  d["converged"] = s.converged;
  d["position_error"] = s.position_error;
  d["rotation_error"] = s.rotation_error;
  d["iterations"] = s.iterations;
  return d;
}

Eigen::VectorXd configuration_vector(const Robot& robot, const Array& q, const char* what) {
  const Array checked = configuration(robot, q, what);
  return Eigen::Map<const Eigen::VectorXd>(checked.data(), checked.shape(0));
}

}  // namespace

void init_ik(py::module_& m) {
  py::enum_<IkTask>(m, "IkTask")
      .value("pose", IkTask::pose)
      .value("position", IkTask::position);
  py::enum_<IkDamping>(m, "IkDamping")
      .value("adaptive", IkDamping::adaptive)
      .value("fixed", IkDamping::fixed);
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
      .def("solve", [](const IkSolver& ik, const Array& T, const Array& seed) {
        const Transform target = pose_arg(T, "target pose");
        const Eigen::VectorXd qs = configuration_vector(ik.robot(), seed, "seed");
        IkSolution s;
        {
          py::gil_scoped_release release;
          s = ik.solve(target, qs);
        }
        return solution_dict(s);
      }, py::arg("target"), py::arg("seed"), "One descent from seed: dict(q, converged, position_error, rotation_error, iterations).")
      .def("solve_path", [](const IkSolver& ik, const Array& P, const Array& seed) {
        const std::vector<Transform> targets = poses_arg(P, "target poses");
        const Eigen::VectorXd qs = configuration_vector(ik.robot(), seed, "seed");
        std::vector<IkSolution> sols;
        {
          py::gil_scoped_release release;
          sols = ik.solve_path(targets, qs);
        }
        const py::ssize_t n = static_cast<py::ssize_t>(sols.size()), dof = ik.robot().dof();
        py::array_t<double> Q({n, dof});
        py::array_t<bool> ok(n);
        for (py::ssize_t i = 0; i < n; ++i) {
          Eigen::Map<Eigen::VectorXd>(Q.mutable_data() + i * dof, dof) = sols[i].q;
          ok.mutable_data()[i] = sols[i].converged;
        }
        return py::make_tuple(Q, ok);
      }, py::arg("targets"), py::arg("seed"),
         "One descent per pose, each from the previous solution: (Q (N, dof), converged (N,)).")
      .def("solve_all", [](const IkSolver& ik, const Array& T, const Array& start) {
        const Transform target = pose_arg(T, "target pose");
        const Eigen::VectorXd qs = configuration_vector(ik.robot(), start, "start");
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
        const std::vector<Transform> targets = poses_arg(P, "target poses");
        const Eigen::VectorXd qs = configuration_vector(ik.robot(), start, "start");
        const py::ssize_t n = static_cast<py::ssize_t>(targets.size()), dof = ik.robot().dof();
        py::array_t<double> Q({n, dof});
        py::array_t<bool> ok(n);
        double* qp = Q.mutable_data();
        bool* okp = ok.mutable_data();
        {
          py::gil_scoped_release release;
          for (py::ssize_t i = 0; i < n; ++i) {
            IkSolution s = ik.solve_any(targets[i], qs);
            Eigen::Map<Eigen::VectorXd>(qp + i * dof, dof) = s.q;
            okp[i] = s.converged;
          }
        }
        return py::make_tuple(Q, ok);
      }, py::arg("targets"), py::arg("start"), "First converged solution per pose: (Q (N, dof), converged (N,)).");
}

}  // namespace pickplan::bind
