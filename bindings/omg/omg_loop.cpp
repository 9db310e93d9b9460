// Native goal selection policies and the Algorithm 2 loop (run with the GIL released).
#include "pickplan/omg/omg_loop.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "refiner_holder.hpp"
#include "trajectory_results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

void init_omg_loop(py::module_& m) {
  py::enum_<SelectionKind>(m, "SelectionKind")
      .value("Fixed", SelectionKind::Fixed)
      .value("Proj", SelectionKind::Proj)
      .value("FTC", SelectionKind::FTC)
      .value("FTL", SelectionKind::FTL)
      .value("EXP", SelectionKind::EXP)
      .value("MD", SelectionKind::MD);
  py::enum_<CostKind>(m, "CostKind").value("objective", CostKind::objective).value("distance", CostKind::distance);
  py::enum_<StageClock>(m, "StageClock").value("wall", StageClock::wall).value("thread_cpu", StageClock::thread_cpu);
  result_class<OmgStageSeconds>(m, "OmgStageSeconds", "Seconds the OMG loop spent in each stage.")
      .field("chomp", &OmgStageSeconds::chomp)
      .field("costs", &OmgStageSeconds::costs)
      .field("selection", &OmgStageSeconds::selection)
      .field("isf", &OmgStageSeconds::isf)
      .field("metrics", &OmgStageSeconds::metrics);
  result_class<OmgLoopResult>(m, "OmgLoopResult", "Algorithm 2's plan, its metrics and the per-iteration history.")
      .field("xi", &OmgLoopResult::xi)
      .field("goal", &OmgLoopResult::goal)
      .field("iterations", &OmgLoopResult::iterations)
      .field("metrics", &OmgLoopResult::metrics)
      .field("grasp_cost", &OmgLoopResult::grasp_cost)
      .field("grasp_index", &OmgLoopResult::grasp_index)
      .field("goal_source", &OmgLoopResult::goal_source)
      .field("goal_set_size", &OmgLoopResult::goal_set_size)
      .field("refined", &OmgLoopResult::refined)
      .field("objective", &OmgLoopResult::objective)
      .field("goals_chosen", &OmgLoopResult::goals_chosen)
      .field("p", &OmgLoopResult::p)
      .field("costs", &OmgLoopResult::costs)
      .field("switches", &OmgLoopResult::switches)
      .field("initial_grasp", &OmgLoopResult::initial_grasp)
      .field("seconds", &OmgLoopResult::seconds);

  py::class_<SelectionSettings>(m, "SelectionSettings")
      .def(py::init<>())
      .def_readwrite("kind", &SelectionSettings::kind)
      .def_readwrite("exp_eta", &SelectionSettings::exp_eta)
      .def_readwrite("md_exponents", &SelectionSettings::md_exponents)
      .def_readwrite("md_shift", &SelectionSettings::md_shift);

  py::class_<SelectionPolicy>(m, "SelectionPolicy", "A native goal selection policy (omg.selection's rules).")
      .def(py::init<SelectionSettings>(), py::arg("settings"))
      .def_property_readonly("kind", &SelectionPolicy::kind)
      .def_property_readonly("cost_kind", &SelectionPolicy::cost_kind)
      .def(
          "reset",
          [](SelectionPolicy& s, int num_goals, int horizon, const py::object& initial) {
            if (initial.is_none()) return s.reset(num_goals, horizon, nullptr);
            const Eigen::VectorXd c = vector_arg(initial.cast<Array>(), "initial costs");
            s.reset(num_goals, horizon, &c);
          },
          py::arg("num_goals"), py::arg("horizon"), py::arg("initial_costs") = py::none())
      .def("add_goal", &SelectionPolicy::add_goal)
      .def(
          "update", [](SelectionPolicy& s, const Array& c) { return s.update(vector_arg(c, "costs")); },
          py::arg("costs"))
      .def("select", &SelectionPolicy::select)
      .def_property_readonly("p", [](const SelectionPolicy& s) { return s.p(); })
      .def("regret", &SelectionPolicy::regret);

  py::class_<OmgLoopSettings>(m, "OmgLoopSettings")
      .def(py::init<>())
      .def_readwrite("selection", &OmgLoopSettings::selection)
      .def_readwrite("iterations", &OmgLoopSettings::iterations)
      .def_readwrite("isf_steps", &OmgLoopSettings::isf_steps)
      .def_readwrite("isf_max_shift", &OmgLoopSettings::isf_max_shift)
      .def_readwrite("cost_time_stride", &OmgLoopSettings::cost_time_stride)
      .def_readwrite("cost_point_stride", &OmgLoopSettings::cost_point_stride)
      .def_readwrite("pre_terminate", &OmgLoopSettings::pre_terminate)
      .def_readwrite("min_iterations", &OmgLoopSettings::min_iterations)
      .def_readwrite("check_every", &OmgLoopSettings::check_every)
      .def_readwrite("metrics", &OmgLoopSettings::metrics)
      .def_readwrite("clock", &OmgLoopSettings::clock);

  m.def(
      "run_omg_loop",
      [](const ChompProblem& problem, const RefinerHolder* refiner, const py::object& hand_link, const Array& q0,
         const Array& goals, const Array& tails, const py::object& grasp_index, const Array& blend,
         const OmgLoopSettings& settings, const py::object& initial, int initial_goal, const py::object& initial_costs,
         const py::object& check) {
        const int hand = link_arg(problem.robot(), hand_link);
        const Trajectory G = configuration_rows(problem.robot(), goals, "goals", "G");
        const std::vector<Trajectory> T = configuration_blocks(problem.robot(), tails, "tails", goals.shape(0));
        const IntArray index = index_array("grasp_index", grasp_index, std::numeric_limits<int>::max());
        if (index.ndim() != 1 || index.shape(0) != goals.shape(0))
          throw std::invalid_argument("grasp_index: expected one entry per goal, got shape " + shape_str(index));
        const std::vector<int> gi(index.data(), index.data() + index.shape(0));
        const Eigen::VectorXd q0v = configuration_vector(problem.robot(), q0, "start configuration");
        const Eigen::VectorXd b = vector_arg(blend, "blend");
        WarmStart warm;
        if (!initial.is_none()) {
          warm.initial = configuration_rows(problem.robot(), initial.cast<Array>(), "initial", "B");
          warm.initial_goal = initial_goal;
          if (!initial_costs.is_none()) warm.initial_costs = vector_arg(initial_costs.cast<Array>(), "initial_costs");
        } else if (initial_goal != -1 || !initial_costs.is_none()) {
          throw std::invalid_argument("initial_goal, initial_costs: given without an initial trajectory");
        }
        PlanCheck plan_check;
        if (!check.is_none())  // Python's test: it takes the GIL the loop releases, at the few checks only
          plan_check = [&check](const Trajectory& xi) {
            py::gil_scoped_acquire acquire;
            return check(Trajectory(xi)).cast<bool>();
          };
        OmgLoopResult r;
        {
          py::gil_scoped_release release;
          r = run_omg_loop(problem, refiner ? refiner->refiner.get() : nullptr, hand, q0v, G, T, gi, b, settings,
                           initial.is_none() ? nullptr : &warm, check.is_none() ? nullptr : &plan_check);
        }
        return r;
      },
      py::arg("problem"), py::arg("refiner"), py::arg("hand_link"), py::arg("q0"), py::arg("goals"), py::arg("tails"),
      py::arg("grasp_index"), py::arg("blend"), py::arg("settings"), py::arg("initial") = py::none(),
      py::arg("initial_goal") = -1, py::arg("initial_costs") = py::none(), py::arg("check") = py::none(),
      "Algorithm 2's loop over a goal set (refiner None: no ISF); returns the plan, its metrics and history. "
      "initial (n, dof), initial_goal and initial_costs (one per goal, or None: estimated): a warm start from a "
      "previous plan (replanning). check: None or a function of a plan (n, dof) -> bool that a plan must also "
      "pass before the loop stops early on it (the exact test among furniture).");
}

}  // namespace pickplan::bind
