// Bindings of the pick-up on the move NLP (pickplan.pickup.planner is the public face).
// Ipopt + MUMPS are not thread-safe: the GIL is released around solves so Python stays
// responsive, but run independent solves in separate processes (planner.solve_many).
#include "pickplan/pickup/nlp.hpp"
#include "../common.hpp"
#include "../results.hpp"
#include "pickplan/pickup/cases.hpp"
#include "pickplan/pickup/stomp.hpp"

using namespace pickplan::core;
using namespace pickplan::pickup;

namespace pickplan::bind {

void init_pickup_nlp(py::module_& m) {
  py::class_<RhoPoly>(m, "RhoPoly")
      .def(py::init([](const Eigen::MatrixXd& coeffs, std::pair<double, double> sg, std::pair<double, double> sc) {
             RhoPoly r;
             r.coeffs = coeffs;
             r.sg_lo = sg.first;
             r.sg_hi = sg.second;
             r.sc_lo = sc.first;
             r.sc_hi = sc.second;
             r.validate();
             return r;
           }),
           py::arg("coeffs"), py::arg("sg_range"), py::arg("sc_range"))
      .def_readonly("coeffs", &RhoPoly::coeffs)
      .def_property_readonly("sg_range", [](const RhoPoly& r) { return std::make_pair(r.sg_lo, r.sg_hi); })
      .def_property_readonly("sc_range", [](const RhoPoly& r) { return std::make_pair(r.sc_lo, r.sc_hi); })
      .def("value", &RhoPoly::value, py::arg("s_g"), py::arg("s_c"))
      .def("gradient", &RhoPoly::gradient, py::arg("s_g"), py::arg("s_c"))
      .def("sg_upper_bound", &RhoPoly::sg_upper_bound, py::arg("gamma"), py::arg("sc_a"), py::arg("sc_b"),
           "the largest S_g with rho >= gamma for some S_c in [sc_a, sc_b] (NaN: none)");

  py::enum_<GraspKind>(m, "GraspKind").value("top", GraspKind::top).value("side", GraspKind::side);
  py::class_<PickupProblem>(m, "PickupProblem")
      .def(py::init<>())
      .def_readwrite("start", &PickupProblem::start)
      .def_readwrite("arm_start", &PickupProblem::arm_start)
      .def_readwrite("goal", &PickupProblem::goal)
      .def_readwrite("goal_tol_pos", &PickupProblem::goal_tol_pos)
      .def_readwrite("goal_tol_yaw", &PickupProblem::goal_tol_yaw)
      .def_property(
          "grasp_pose", [](const PickupProblem& p) { return Eigen::Matrix4d(p.grasp_pose.matrix()); },
          [](PickupProblem& p, const Array& M) { p.grasp_pose = Transform::from_matrix(matrix4(M, "grasp_pose")); })
      .def_readwrite("approach_dir", &PickupProblem::approach_dir)
      .def_readwrite("part_xy", &PickupProblem::part_xy)
      .def_readwrite("grasp_area_rmin", &PickupProblem::grasp_area_rmin)
      .def_readwrite("grasp_area_rmax", &PickupProblem::grasp_area_rmax)
      .def_readwrite("rho", &PickupProblem::rho)
      .def_readwrite("gamma", &PickupProblem::gamma)
      .def_readwrite("stroke", &PickupProblem::stroke)
      .def_readwrite("vary_sc", &PickupProblem::vary_sc)
      .def_readwrite("sc_fixed", &PickupProblem::sc_fixed)
      .def_readwrite("base_speed_limit", &PickupProblem::base_speed_limit)
      .def_readwrite("base_yaw_rate_limit", &PickupProblem::base_yaw_rate_limit)
      .def_readwrite("arm_rate_limits", &PickupProblem::arm_rate_limits)
      .def_readwrite("tool_link", &PickupProblem::tool_link)
      .def_property(
          "obstacles",
          [](const PickupProblem& p) {
            py::list out;
            for (const auto& o : p.obstacles) out.append(py::make_tuple(o.center, o.radius));
            return out;
          },
          [](PickupProblem& p, const std::vector<std::pair<Eigen::Vector3d, double>>& v) {
            p.obstacles.clear();
            for (const auto& [c, r] : v) p.obstacles.push_back({c, r});
          })
      .def_property(
          "body_spheres",
          [](const PickupProblem& p) {
            py::list out;
            for (const auto& b : p.body_spheres) out.append(py::make_tuple(b.link, b.center, b.radius));
            return out;
          },
          [](PickupProblem& p, const std::vector<std::tuple<int, Eigen::Vector3d, double>>& v) {
            p.body_spheres.clear();
            for (const auto& [l, c, r] : v) p.body_spheres.push_back({l, c, r});
          })
      .def("set_part_grasp", &set_part_grasp, py::arg("kind"), py::arg("yaw"), py::arg("position"),
           "grasp pose, approach direction and grasping-area centre of a part at `position` with `yaw`")
      .def("validate", &PickupProblem::validate, py::arg("robot"));

  py::enum_<HessianMode>(m, "HessianMode")
      .value("exact", HessianMode::exact)
      .value("limited_memory", HessianMode::limited_memory);
  py::enum_<CoefficientBasis>(m, "CoefficientBasis")
      .value("bernstein", CoefficientBasis::bernstein)
      .value("monomial", CoefficientBasis::monomial);
  py::enum_<MuStrategy>(m, "MuStrategy")
      .value("monotone", MuStrategy::monotone)
      .value("adaptive", MuStrategy::adaptive);
  py::enum_<RateRows>(m, "RateRows").value("hull", RateRows::hull).value("sampled", RateRows::sampled);
  {
    py::enum_<SolveStatus> status(m, "SolveStatus");
    for (SolveStatus s :
         {SolveStatus::not_run, SolveStatus::solved, SolveStatus::solved_acceptable, SolveStatus::infeasible,
          SolveStatus::diverging, SolveStatus::max_iterations, SolveStatus::max_cpu_time,
          SolveStatus::restoration_failed, SolveStatus::step_too_small, SolveStatus::invalid_number,
          SolveStatus::solver_error, SolveStatus::bounded, SolveStatus::violation_between_samples,
          SolveStatus::constraint_violation, SolveStatus::time_limit})
      status.value(to_string(s), s);
  }

  py::class_<PickupSettings>(m, "PickupSettings")
      .def(py::init<>())
      .def_readwrite("samples_per_interval", &PickupSettings::samples_per_interval)
      .def_readwrite("degrees", &PickupSettings::degrees)
      .def_readwrite("nonholonomic_tol", &PickupSettings::nonholonomic_tol)
      .def_readwrite("velocity_tol", &PickupSettings::velocity_tol)
      .def_readwrite("angular_velocity_tol", &PickupSettings::angular_velocity_tol)
      .def_readwrite("collision_margin", &PickupSettings::collision_margin)
      .def_readwrite("joint_limit_margin", &PickupSettings::joint_limit_margin)
      .def_readwrite("timing_fraction", &PickupSettings::timing_fraction)
      .def_readwrite("direct_track", &PickupSettings::direct_track)
      .def_readwrite("arm_seeds", &PickupSettings::arm_seeds)
      .def_readwrite("t_min", &PickupSettings::t_min)
      .def_readwrite("t_max", &PickupSettings::t_max)
      .def_readwrite("tol", &PickupSettings::tol)
      .def_readwrite("constr_viol_tol", &PickupSettings::constr_viol_tol)
      .def_readwrite("max_iter", &PickupSettings::max_iter)
      .def_readwrite("max_cpu_time", &PickupSettings::max_cpu_time)
      .def_readwrite("print_level", &PickupSettings::print_level)
      .def_readwrite("hessian", &PickupSettings::hessian)
      .def_readwrite("basis", &PickupSettings::basis)
      .def_readwrite("active_set", &PickupSettings::active_set)
      .def_readwrite("active_joint_window", &PickupSettings::active_joint_window)
      .def_readwrite("active_collision_window", &PickupSettings::active_collision_window)
      .def_readwrite("active_max_rounds", &PickupSettings::active_max_rounds)
      .def_readwrite("mu_resolve", &PickupSettings::mu_resolve)
      .def_readwrite("dense_subdivisions", &PickupSettings::dense_subdivisions)
      .def_readwrite("dense_nonholonomic", &PickupSettings::dense_nonholonomic)
      .def_readwrite("mu_strategy", &PickupSettings::mu_strategy)
      .def_readwrite("mu_init", &PickupSettings::mu_init)
      .def_readwrite("seed", &PickupSettings::seed)
      .def_readwrite("arm_seed_noise", &PickupSettings::arm_seed_noise)
      .def_readwrite("ipopt_options", &PickupSettings::ipopt_options)
      .def_readwrite("rate_rows", &PickupSettings::rate_rows)
      .def_readwrite("rate_hull_degree", &PickupSettings::rate_hull_degree)
      .def_readwrite("derivative_test", &PickupSettings::derivative_test)
      .def_readwrite("output_file", &PickupSettings::output_file)
      .def_readwrite("warm_start_push", &PickupSettings::warm_start_push)
      .def_readwrite("timing_seed", &PickupSettings::timing_seed)
      .def_readwrite("direct_max_iter", &PickupSettings::direct_max_iter)
      .def_readwrite("warm_start_stages", &PickupSettings::warm_start_stages)
      .def_readwrite("time_limit", &PickupSettings::time_limit)
      .def_readwrite("seed_speed", &PickupSettings::seed_speed);

  py::class_<StageResult>(m, "StageResult")
      .def_readonly("stage", &StageResult::stage)
      .def_readonly("status", &StageResult::status)
      .def_readonly("ipopt_status", &StageResult::ipopt_status)
      .def_readonly("success", &StageResult::success)
      .def_readonly("seconds", &StageResult::seconds)
      .def_readonly("cpu_seconds", &StageResult::cpu_seconds)
      .def_readonly("iterations", &StageResult::iterations)
      .def_readonly("rounds", &StageResult::rounds)
      .def_readonly("rows", &StageResult::rows)
      .def_readonly("objective", &StageResult::objective)
      .def_readonly("max_violation", &StageResult::max_violation)
      .def_readonly("x", &StageResult::x);

  py::class_<PickupResult>(m, "PickupResult")
      .def_readonly("status", &PickupResult::status)
      .def_readonly("success", &PickupResult::success)
      .def_readonly("stages_completed", &PickupResult::stages_completed)
      .def_readonly("stages", &PickupResult::stages)
      .def_readonly("x", &PickupResult::x)
      .def_readonly("total_seconds", &PickupResult::total_seconds)
      .def_readonly("total_cpu_seconds", &PickupResult::total_cpu_seconds)
      .def_readonly("T", &PickupResult::T)
      .def_readonly("T1", &PickupResult::T1)
      .def_readonly("T2", &PickupResult::T2)
      .def_readonly("S_g", &PickupResult::S_g)
      .def_readonly("S_c", &PickupResult::S_c)
      .def_readonly("direct", &PickupResult::direct)
      .def_readonly("direct_chosen", &PickupResult::direct_chosen)
      .def_readonly("arm_seeds_tried", &PickupResult::arm_seeds_tried)
      .def_readonly("arm_seed_chosen", &PickupResult::arm_seed_chosen)
      .def_readonly("arm_seed_T", &PickupResult::arm_seed_T)
      .def_readonly("search_seconds", &PickupResult::search_seconds)
      .def_readonly("search_cpu_seconds", &PickupResult::search_cpu_seconds)
      .def_property_readonly("degrees", [](const PickupResult& r) { return r.traj.degrees(); })
      .def(
          "sample",
          [](const PickupResult& r, const Eigen::VectorXd& times) {
            if (r.x.size() != r.traj.num_coeffs() + 5) throw std::invalid_argument("result holds no trajectory");
            Eigen::MatrixXd q, qd, qdd;
            r.traj.eval_many(r.x.head(r.traj.num_coeffs()), times, &q, &qd, &qdd);
            return py::make_tuple(q, qd, qdd);
          },
          py::arg("times"), "q, q', q'' at the given times (s), each (len(times), dof)");

  m.def(
      "pickup_paper_case",
      [](const Robot& robot, int case_id, const RhoPoly& rho, double gamma, double arm_rate, bool obstacles,
         double part_z) {
        PaperCaseOptions o;
        o.gamma = gamma;
        o.arm_rate = arm_rate;
        o.obstacles = obstacles;
        o.part_z = part_z;
        return paper_case(robot, case_id, rho, o);
      },
      py::arg("robot"), py::arg("case_id"), py::arg("rho"), py::arg("gamma") = 0.96, py::arg("arm_rate") = M_PI,
      py::arg("obstacles") = true, py::arg("part_z") = 0.5);
  m.def("pickup_example_rho", &example_rho, py::arg("shift") = 0.0);
  m.def("pickup_heuristic_seed", &heuristic_seed, py::arg("robot"), py::arg("problem"), py::arg("settings"));
  m.def("pickup_random_seed", &random_seed, py::arg("robot"), py::arg("problem"), py::arg("settings"));
  m.def("pickup_solve_stage", &solve_stage, py::arg("robot"), py::arg("problem"), py::arg("settings"), py::arg("stage"),
        py::arg("x0"), py::call_guard<py::gil_scoped_release>());
  m.def(
      "pickup_solve_successive",
      [](const Robot& r, const PickupProblem& p, const PickupSettings& s, const Eigen::VectorXd& x0) {
        return solve_successive(r, p, s, x0);
      },
      py::arg("robot"), py::arg("problem"), py::arg("settings"), py::arg("x0") = Eigen::VectorXd(),
      py::call_guard<py::gil_scoped_release>());
  m.def("pickup_solve_single_shot", &solve_single_shot, py::arg("robot"), py::arg("problem"), py::arg("settings"),
        py::arg("x0") = Eigen::VectorXd(), py::call_guard<py::gil_scoped_release>());
  py::class_<StompSettings>(m, "StompSettings")
      .def(py::init<>())
      .def_readwrite("iterations", &StompSettings::iterations)
      .def_readwrite("rollouts", &StompSettings::rollouts)
      .def_readwrite("noise_stddev", &StompSettings::noise_stddev)
      .def_readwrite("temperature", &StompSettings::temperature)
      .def_readwrite("control_weight", &StompSettings::control_weight)
      .def_readwrite("obstacle_weight", &StompSettings::obstacle_weight)
      .def_readwrite("limit_weight", &StompSettings::limit_weight)
      .def_readwrite("margin", &StompSettings::margin)
      .def_readwrite("seed", &StompSettings::seed);
  py::class_<StompResult>(m, "StompResult")
      .def_readonly("q", &StompResult::q)
      .def_readonly("initial_cost", &StompResult::initial_cost)
      .def_readonly("final_cost", &StompResult::final_cost)
      .def_readonly("initial_smoothness", &StompResult::initial_smoothness)
      .def_readonly("final_smoothness", &StompResult::final_smoothness)
      .def_readonly("max_rate", &StompResult::max_rate)
      .def_readonly("min_clearance", &StompResult::min_clearance)
      .def_readonly("limits_ok", &StompResult::limits_ok)
      .def_readonly("iterations", &StompResult::iterations)
      .def_readonly("seconds", &StompResult::seconds);
  m.def(
      "stomp_refine",
      [](const Robot& robot, const Eigen::MatrixXd& Q, double dt, const Eigen::VectorXd& rate,
         const std::vector<std::tuple<int, Eigen::Vector3d, double>>& spheres,
         const std::vector<std::pair<Eigen::Vector3d, double>>& obstacles, const StompSettings& st) {
        std::vector<BodySphere> b;
        for (const auto& [l, c, r] : spheres) b.push_back({l, c, r});
        std::vector<SphereObstacle> o;
        for (const auto& [c, r] : obstacles) o.push_back({c, r});
        py::gil_scoped_release release;
        return stomp_refine(robot, Q, dt, rate, b, o, st);
      },
      py::arg("robot"), py::arg("q"), py::arg("dt"), py::arg("arm_rate_limits"), py::arg("body_spheres"),
      py::arg("obstacles"), py::arg("settings") = StompSettings());
  result_class<PickupMetrics>(m, "PickupMetrics", "Dense re-sampling checks of a pick-up plan (cases.hpp).")
      .field("pose_error_position", &PickupMetrics::pose_error_position)
      .field("pose_error_orientation", &PickupMetrics::pose_error_orientation)
      .field("nonholonomic_mean", &PickupMetrics::nonholonomic_mean)
      .field("nonholonomic_drift", &PickupMetrics::nonholonomic_drift)
      .field("nonholonomic_max", &PickupMetrics::nonholonomic_max)
      .field("joint_limit_violation", &PickupMetrics::joint_limit_violation)
      .field("joint_rate_max", &PickupMetrics::joint_rate_max)
      .field("base_speed_max", &PickupMetrics::base_speed_max)
      .field("base_speed_grasp_mean", &PickupMetrics::base_speed_grasp_mean)
      .field("gripper_speed_grasp_mean", &PickupMetrics::gripper_speed_grasp_mean)
      .field("velocity_error_max", &PickupMetrics::velocity_error_max)
      .field("min_clearance", &PickupMetrics::min_clearance)
      .field("goal_position_error", &PickupMetrics::goal_position_error)
      .field("success_probability", &PickupMetrics::success_probability);
  m.def("pickup_evaluate", &evaluate_pickup, py::arg("robot"), py::arg("problem"), py::arg("result"),
        py::arg("n") = 2001);
}

}  // namespace pickplan::bind
