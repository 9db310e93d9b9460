#include "../common.hpp"
#include "pickplan/omg/chomp.hpp"
#include "pickplan/omg/metrics.hpp"
#include "trajectory_results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

Trajectory traj_arg(const ChompProblem& p, const Array& a, const char* what) {
  const std::string desc = "(" + std::to_string(p.settings().n) + ", " + std::to_string(p.robot().dof()) + ")";
  require_shape(what, a, {p.settings().n, p.robot().dof()}, desc.c_str());
  require_finite_array(what, a);
  return Eigen::Map<const Trajectory>(a.data(), a.shape(0), a.shape(1));
}

Eigen::VectorXd q_arg(const ChompProblem& p, const Array& q) {
  Array c = configuration(p.robot(), q, "start configuration");
  return Eigen::Map<const Eigen::VectorXd>(c.data(), c.shape(0));
}

Trajectory goal_arg(const ChompProblem& p, const Array& g) {
  if (g.ndim() == 1) {
    Array c = configuration(p.robot(), g, "goal");
    return Eigen::Map<const Trajectory>(c.data(), 1, c.shape(0));
  }
  const std::string desc = "(m, " + std::to_string(p.robot().dof()) + ")";
  require_shape("goal", g, {-1, p.robot().dof()}, desc.c_str());
  require_finite_array("goal", g);
  return Eigen::Map<const Trajectory>(g.data(), g.shape(0), g.shape(1));
}

py::dict terms_dict(const ObjectiveTerms& t) {
  py::dict d;
  d["obstacle"] = t.obstacle;
  d["prior"] = t.prior;
  d["total"] = t.total;
  d["colliding_points"] = t.colliding_points;
  return d;
}

}  // namespace

void init_chomp(py::module_& m) {
  py::enum_<ChompStatus>(m, "ChompStatus").value("ok", ChompStatus::ok);
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
               throw std::invalid_argument("body links: expected shape (" + std::to_string(points.shape(0)) + ",), got " +
                                           shape_str(links));
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
      .def("solve_A", [](const ChompProblem& p, const Array& v) {
        Trajectory V = traj_arg(p, v, "v"), out;
        p.solve_A(V, out);
        return to_array(out);
      })
      .def("prior", [](const ChompProblem& p, const Array& xi, const Array& q0) {
        Trajectory X = traj_arg(p, xi, "trajectory"), g;
        const double f = p.prior(X, q_arg(p, q0), &g);
        return py::make_tuple(f, to_array(g));
      }, py::arg("xi"), py::arg("q0"))
      .def("obstacle", [](const ChompProblem& p, const Array& xi, const Array& q0) {
        Trajectory X = traj_arg(p, xi, "trajectory"), g = Trajectory::Zero(X.rows(), X.cols());
        Eigen::VectorXd q = q_arg(p, q0);
        ObjectiveTerms t;
        {
          py::gil_scoped_release release;
          ChompWorkspace ws(p);
          t = p.obstacle(X, q, &g, ws);
        }
        return py::make_tuple(terms_dict(t), to_array(g));
      }, py::arg("xi"), py::arg("q0"), "f_obstacle over the top-k terms and its gradient.")
      .def("objective", [](const ChompProblem& p, const Array& xi, const Array& q0, int iteration) {
        Trajectory X = traj_arg(p, xi, "trajectory"), g;
        Eigen::VectorXd q = q_arg(p, q0);
        ObjectiveTerms t;
        {
          py::gil_scoped_release release;
          ChompWorkspace ws(p);
          t = p.objective(X, q, iteration, &g, ws);
        }
        return py::make_tuple(terms_dict(t), to_array(g));
      }, py::arg("xi"), py::arg("q0"), py::arg("iteration") = 0)
      .def("step", [](const ChompProblem& p, const Array& xi, const Array& q0, const py::object& goal, int iteration,
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
        py::dict d;
        d["before"] = terms_dict(info.before);
        d["goal_error"] = info.goal_error;
        d["limit_projections"] = info.limit_projections;
        return py::make_tuple(to_array(X), d);
      }, py::arg("xi"), py::arg("q0"), py::arg("goal") = py::none(), py::arg("iteration") = 0,
         py::arg("workspace") = nullptr, "One CHOMP (goal=None: fixed end) or CHOMP-Proj step; returns (xi, info).")
      .def("optimize", [](const ChompProblem& p, const Array& xi, const Array& q0, const Array& goal, int iterations) {
        Trajectory X = traj_arg(p, xi, "trajectory");
        Eigen::VectorXd q = q_arg(p, q0);
        Trajectory G = goal_arg(p, goal);
        if (iterations < 0) throw std::invalid_argument("iterations must be >= 0");
        ChompResult r;
        {
          py::gil_scoped_release release;
          r = p.optimize(X, q, G, iterations);
        }
        py::dict d;
        d["xi"] = to_array(r.xi);
        d["objective"] = r.objective;
        d["final"] = terms_dict(r.final_terms);
        d["iterations"] = r.iterations;
        d["status"] = r.status;
        d["seconds"] = r.seconds;
        return d;
      }, py::arg("xi"), py::arg("q0"), py::arg("goal"), py::arg("iterations"))
      .def("goal_costs", [](const ChompProblem& p, const Array& xi, const Array& q0, int iteration, int horizon,
                            const Array& goals, int time_stride, int point_stride, ChompWorkspace* ws) {
        Trajectory X = traj_arg(p, xi, "trajectory");
        Eigen::VectorXd q = q_arg(p, q0);
        const std::string desc = "(G, " + std::to_string(p.robot().dof()) + ")";
        require_shape("goals", goals, {-1, p.robot().dof()}, desc.c_str());
        require_finite_array("goals", goals);
        Trajectory G = Eigen::Map<const Trajectory>(goals.data(), goals.shape(0), goals.shape(1));
        py::array_t<double> out(G.rows());
        double* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          std::unique_ptr<ChompWorkspace> own;
          if (!ws) ws = (own = std::make_unique<ChompWorkspace>(p)).get();
          p.goal_costs(X, q, iteration, horizon, G, time_stride, point_stride, o, *ws);
        }
        return out;
      }, py::arg("xi"), py::arg("q0"), py::arg("iteration"), py::arg("horizon"), py::arg("goals"),
         py::arg("time_stride") = 1, py::arg("point_stride") = 1, py::arg("workspace") = nullptr,
         "OMG goal-cost estimates (unnormalized) of a constant-velocity tail from xi(t_i) to each goal.")
      .def("metrics", [](const ChompProblem& p, const Array& xi, const Array& q0, const MetricSettings& s) {
        Trajectory X = traj_arg(p, xi, "trajectory");
        Eigen::VectorXd q = q_arg(p, q0);
        TrajectoryMetrics mt;
        {
          py::gil_scoped_release release;
          mt = evaluate_trajectory(p, q, X, s);
        }
        return metrics_dict(mt);
      }, py::arg("xi"), py::arg("q0"), py::arg("settings"));

  m.def("interpolate", [](const Array& q0, const Array& xi, int steps) {
    require_shape("trajectory", xi, {-1, q0.shape(0)}, "(n, dof)");
    Eigen::VectorXd q = Eigen::Map<const Eigen::VectorXd>(q0.data(), q0.shape(0));
    return to_array(interpolate(q, Eigen::Map<const Trajectory>(xi.data(), xi.shape(0), xi.shape(1)), steps));
  }, py::arg("q0"), py::arg("xi"), py::arg("steps"));
}

}  // namespace pickplan::bind
