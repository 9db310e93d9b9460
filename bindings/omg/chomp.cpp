#include "pickplan/omg/chomp.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"
#include "pickplan/omg/metrics.hpp"
#include "trajectory_results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

Trajectory traj_arg(const ChompProblem& p, const Array& a, const char* what) {
  return configuration_rows(p.robot(), a, what, "n", p.settings().n);
}

Eigen::VectorXd q_arg(const ChompProblem& p, const Array& q) {
  return configuration_vector(p.robot(), q, "start configuration");
}

Trajectory goal_arg(const ChompProblem& p, const Array& g) {
  if (g.ndim() == 1) return configuration_vector(p.robot(), g, "goal").transpose();
  return configuration_rows(p.robot(), g, "goal", "m");
}

}  // namespace

void init_chomp(py::module_& m) {
  py::enum_<ChompStatus>(m, "ChompStatus").value("ok", ChompStatus::ok);
  result_class<ObjectiveTerms>(m, "ObjectiveTerms", "CHOMP objective terms: total = obstacle + lambda * prior.")
      .field("obstacle", &ObjectiveTerms::obstacle)
      .field("prior", &ObjectiveTerms::prior)
      .field("total", &ObjectiveTerms::total)
      .field("colliding_points", &ObjectiveTerms::colliding_points);
  result_class<StepInfo>(m, "StepInfo", "One CHOMP step: the terms it started from, the goal error, limit projections.")
      .field("before", &StepInfo::before)
      .field("goal_error", &StepInfo::goal_error)
      .field("limit_projections", &StepInfo::limit_projections);
  result_class<ChompResult>(m, "ChompResult", "CHOMP iterations: the trajectory, objective history, final terms.")
      .field("xi", &ChompResult::xi)
      .field("objective", &ChompResult::objective)
      .field("final_terms", &ChompResult::final_terms)
      .field("iterations", &ChompResult::iterations)
      .field("status", &ChompResult::status)
      .field("seconds", &ChompResult::seconds);
  bind_trajectory_metrics(m);
  py::class_<ChompSettings>(m, "ChompSettings")
      .def(py::init<>())
      .def_readwrite("n", &ChompSettings::n)
      .def_readwrite("duration", &ChompSettings::duration)
      .def_readwrite("lambda_", &ChompSettings::lambda)
      .def_readwrite("lambda_growth", &ChompSettings::lambda_growth)
      .def_readwrite("step_size", &ChompSettings::step_size)
      .def_readwrite("epsilon", &ChompSettings::epsilon)
      .def_readwrite("top_k", &ChompSettings::top_k)
      .def_readwrite("clip_gradient", &ChompSettings::clip_gradient)
      .def_readwrite("joint_limit_steps", &ChompSettings::joint_limit_steps)
      .def_readwrite("obstacle_tail", &ChompSettings::obstacle_tail)
      .def_readwrite("exclude_mask", &ChompSettings::exclude_mask)
      .def_readwrite("link_culling", &ChompSettings::link_culling)
      .def_readwrite("active", &ChompSettings::active);

  py::class_<MetricSettings>(m, "MetricSettings")
      .def(py::init<>())
      .def_readwrite("steps", &MetricSettings::steps)
      .def_readwrite("collision_padding", &MetricSettings::collision_padding)
      .def_readwrite("epsilon", &MetricSettings::epsilon)
      .def_readwrite("clearance", &MetricSettings::clearance)
      .def_readwrite("table_clearance", &MetricSettings::table_clearance)
      .def_readwrite("support_link_mask", &MetricSettings::support_link_mask)
      .def_readwrite("support_tolerance", &MetricSettings::support_tolerance)
      .def_readwrite("tail_waypoints", &MetricSettings::tail_waypoints)
      .def_readwrite("tail_clearance", &MetricSettings::tail_clearance)
      .def_readwrite("smoothness_threshold", &MetricSettings::smoothness_threshold)
      .def_readwrite("exclude_mask", &MetricSettings::exclude_mask)
      .def_readwrite("transit_target_clearance", &MetricSettings::transit_target_clearance);

  py::class_<ChompWorkspace>(m, "ChompWorkspace", "Reusable scratch for a ChompProblem (one per thread).");

  py::class_<ChompProblem, std::shared_ptr<ChompProblem>>(m, "ChompProblem")
      .def(py::init([](std::shared_ptr<Robot> robot, std::shared_ptr<SceneSdf> scene, const py::object& link_values,
                       const Array& points, const ChompSettings& settings) {
             require_shape("body points", points, {-1, 3}, "(N, 3)");
             if (!robot) throw std::invalid_argument("robot: expected a Robot, got None");
             const IntArray links = index_array("links", link_values, robot->num_links());
             if (links.ndim() != 1 || links.shape(0) != points.shape(0))
               throw std::invalid_argument("body links: expected shape (" + std::to_string(points.shape(0)) +
                                           ",), got " + shape_str(links));
             BodyPoints body;
             body.link.assign(links.data(), links.data() + links.shape(0));
             body.points = Eigen::Map<const Vertices>(points.data(), points.shape(0), 3);
             return std::make_shared<ChompProblem>(robot, scene, std::move(body), settings);
           }),
           py::arg("robot"), py::arg("scene"), py::arg("links"), py::arg("points"), py::arg("settings"))
      .def_property_readonly("dt", &ChompProblem::dt)
      .def_property_readonly("settings", &ChompProblem::settings)
      .def("workspace", [](const ChompProblem& p) { return std::make_unique<ChompWorkspace>(p); })
      .def("A_matrix", &ChompProblem::A_matrix)
      .def("solve_A",
           [](const ChompProblem& p, const Array& v) {
             Trajectory V = traj_arg(p, v, "v"), out;
             p.solve_A(V, out);
             return rows_array(out);
           })
      .def(
          "prior",
          [](const ChompProblem& p, const Array& xi, const Array& q0) {
            Trajectory X = traj_arg(p, xi, "trajectory"), g;
            const double f = p.prior(X, q_arg(p, q0), &g);
            return py::make_tuple(f, rows_array(g));
          },
          py::arg("xi"), py::arg("q0"))
      .def(
          "obstacle",
          [](const ChompProblem& p, const Array& xi, const Array& q0) {
            Trajectory X = traj_arg(p, xi, "trajectory"), g = Trajectory::Zero(X.rows(), X.cols());
            Eigen::VectorXd q = q_arg(p, q0);
            ObjectiveTerms t;
            {
              py::gil_scoped_release release;
              ChompWorkspace ws(p);
              t = p.obstacle(X, q, &g, ws);
            }
            return py::make_tuple(t, rows_array(g));
          },
          py::arg("xi"), py::arg("q0"), "f_obstacle over the top-k terms and its gradient.")
      .def(
          "objective",
          [](const ChompProblem& p, const Array& xi, const Array& q0, int iteration) {
            Trajectory X = traj_arg(p, xi, "trajectory"), g;
            Eigen::VectorXd q = q_arg(p, q0);
            ObjectiveTerms t;
            {
              py::gil_scoped_release release;
              ChompWorkspace ws(p);
              t = p.objective(X, q, iteration, &g, ws);
            }
            return py::make_tuple(t, rows_array(g));
          },
          py::arg("xi"), py::arg("q0"), py::arg("iteration") = 0)
      .def(
          "step",
          [](const ChompProblem& p, const Array& xi, const Array& q0, const py::object& goal, int iteration,
             ChompWorkspace* ws) {
            Trajectory X = traj_arg(p, xi, "trajectory");
            Eigen::VectorXd q = q_arg(p, q0);
            Trajectory G;
            const bool has_goal = !goal.is_none();
            if (has_goal) G = goal_arg(p, goal.cast<Array>());
            StepInfo info;
            {
              py::gil_scoped_release release;
              std::unique_ptr<ChompWorkspace> own;
              if (!ws) ws = (own = std::make_unique<ChompWorkspace>(p)).get();
              info = p.step(X, q, has_goal ? &G : nullptr, iteration, *ws);
            }
            return py::make_tuple(rows_array(X), info);
          },
          py::arg("xi"), py::arg("q0"), py::arg("goal") = py::none(), py::arg("iteration") = 0,
          py::arg("workspace") = nullptr, "One CHOMP (goal=None: fixed end) or CHOMP-Proj step; returns (xi, info).")
      .def(
          "optimize",
          [](const ChompProblem& p, const Array& xi, const Array& q0, const Array& goal, int iterations) {
            Trajectory X = traj_arg(p, xi, "trajectory");
            Eigen::VectorXd q = q_arg(p, q0);
            Trajectory G = goal_arg(p, goal);
            if (iterations < 0) throw std::invalid_argument("iterations must be >= 0");
            ChompResult r;
            {
              py::gil_scoped_release release;
              r = p.optimize(X, q, G, iterations);
            }
            return r;
          },
          py::arg("xi"), py::arg("q0"), py::arg("goal"), py::arg("iterations"))
      .def(
          "goal_costs",
          [](const ChompProblem& p, const Array& xi, const Array& q0, int iteration, int horizon, const Array& goals,
             int time_stride, int point_stride, ChompWorkspace* ws) {
            Trajectory X = traj_arg(p, xi, "trajectory");
            Eigen::VectorXd q = q_arg(p, q0);
            Trajectory G = configuration_rows(p.robot(), goals, "goals", "G");
            py::array_t<double> out(G.rows());
            double* o = out.mutable_data();
            {
              py::gil_scoped_release release;
              std::unique_ptr<ChompWorkspace> own;
              if (!ws) ws = (own = std::make_unique<ChompWorkspace>(p)).get();
              p.goal_costs(X, q, iteration, horizon, G, time_stride, point_stride, o, *ws);
            }
            return out;
          },
          py::arg("xi"), py::arg("q0"), py::arg("iteration"), py::arg("horizon"), py::arg("goals"),
          py::arg("time_stride") = 1, py::arg("point_stride") = 1, py::arg("workspace") = nullptr,
          "OMG goal-cost estimates (unnormalized) of a constant-velocity tail from xi(t_i) to each goal.")
      .def(
          "metrics",
          [](const ChompProblem& p, const Array& xi, const Array& q0, const MetricSettings& s) {
            Trajectory X = traj_arg(p, xi, "trajectory");
            Eigen::VectorXd q = q_arg(p, q0);
            TrajectoryMetrics mt;
            {
              py::gil_scoped_release release;
              mt = evaluate_trajectory(p, q, X, s);
            }
            return mt;
          },
          py::arg("xi"), py::arg("q0"), py::arg("settings"));

  m.def(
      "interpolate",
      [](const Array& q0, const Array& xi, int steps) {
        require_shape("trajectory", xi, {-1, q0.shape(0)}, "(n, dof)");
        Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(q0.data(), q0.shape(0));
        return rows_array(interpolate(q, Eigen::Map<const Trajectory>(xi.data(), xi.shape(0), xi.shape(1)), steps));
      },
      py::arg("q0"), py::arg("xi"), py::arg("steps"));
}

}  // namespace pickplan::bind
