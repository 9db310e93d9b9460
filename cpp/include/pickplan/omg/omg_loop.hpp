#pragma once
// The loop of OMG's Algorithm 2, native: per iteration a CHOMP-Proj step toward the selected
// goal's tail, the goal-cost estimates, the selection policy's update, C-Space ISF on the selected
// goal (its refined copy joins the goal set), pre-termination by the dense success test; then the
// projection onto the last selection and the success test of the returned trajectory. The same
// steps, in the same order, as python/pickplan/omg/planner.py's _Optimization (the reference).
#include <functional>
#include <map>
#include <set>
#include <vector>

#include <Eigen/Core>

#include "pickplan/omg/chomp.hpp"
#include "pickplan/omg/isf.hpp"
#include "pickplan/omg/metrics.hpp"
#include "pickplan/omg/selection.hpp"

namespace pickplan::omg {

enum class StageClock { wall, thread_cpu };  // what the stage timings read

struct OmgLoopSettings {
  SelectionSettings selection;
  int iterations = 50;          // N
  int isf_steps = 1;            // ISF steps per iteration (with a refiner)
  double isf_max_shift = 0.01;  // m: the hand may move at most this far from its input grasp
  int cost_time_stride = 2, cost_point_stride = 2;
  bool pre_terminate = true;
  int min_iterations = 10, check_every = 5;
  MetricSettings metrics;  // the success test (tail_waypoints: the standoff approach)
  StageClock clock = StageClock::wall;
};

// The goal set as the planner changes it (planner.py's GoalBook): ISF's first move of a goal adds
// a refined copy; later refinements update that copy. Goals ISF cannot improve are left alone.
class GoalBook {
 public:
  GoalBook(const core::Robot& robot, int hand_link, const Trajectory& goals, std::vector<Trajectory> tails,
           std::vector<int> grasp_index);
  int size() const { return static_cast<int>(goals_.size()); }
  int tail_length() const { return static_cast<int>(tails_.front().rows()); }
  bool on_goal(const Trajectory& xi, int g) const;
  bool is_refined(int g) const;
  bool stalled(int g) const { return stalled_.count(g) > 0; }
  // ISF steps on goal g: the goal to follow (g or its refined copy) and whether that copy is new.
  std::pair<int, bool> refine(int g, const GraspRefiner& refiner, int steps, double max_shift);
  const Eigen::VectorXd& goal(int g) const { return goals_[g]; }
  const Trajectory& tail(int g) const { return tails_[g]; }
  int origin(int g) const { return origin_[g]; }
  int origin_goal(int g) const { return origin_goal_[g]; }
  Trajectory goal_matrix() const;

 private:
  Eigen::Vector3d hand_position(const Eigen::VectorXd& q);
  const core::Robot& robot_;
  int hand_;
  core::RobotWorkspace fk_;
  std::vector<Eigen::VectorXd> goals_;
  std::vector<Trajectory> tails_;
  std::vector<int> origin_, origin_goal_;
  std::map<int, int> refined_copy_;
  std::set<int> stalled_;
  std::map<int, Eigen::Vector3d> grasp_hand_;
};

struct OmgStageSeconds {
  double chomp = 0, costs = 0, selection = 0, isf = 0, metrics = 0;
};

struct OmgLoopResult {
  Trajectory xi;  // n x dof, after the start
  int goal = -1;  // book index of the final goal
  int iterations = 0;
  TrajectoryMetrics metrics;  // of xi
  double grasp_cost = 0;      // f_grasp at the final goal (NaN without a refiner)
  int grasp_index = -1, goal_source = -1, goal_set_size = 0;
  bool refined = false;
  // history, per iteration
  std::vector<double> objective;
  std::vector<int> goals_chosen;
  std::vector<Eigen::VectorXd> p, costs;
  int switches = 0, initial_grasp = -1;
  OmgStageSeconds seconds;
};

// Algorithm 2 from q0 over the goal set (goals G x dof, tails per goal m x dof with m the same for
// all, grasp_index per goal). blend: n initialization fractions (waypoint t = q0 + blend[t] (g - q0),
// the cubic's from Python so both loops start bit-equal). refiner: null = no ISF.
// A warm start (replanning) gives `initial` (n x dof, after the start: the last plan moved to the new
// start) and `initial_goal` (its goal in this goal set, or -1: the best by the first estimate): the
// loop starts there with that goal's tail, and a start that already passes the success test on its
// goal is returned with no iteration. `initial_costs` (one per goal, or empty): the goal costs the
// selection policy starts from (the last plan's latest estimates of these goals); empty: estimated.
struct WarmStart {
  Trajectory initial;
  int initial_goal = -1;
  Eigen::VectorXd initial_costs;
};
// A test a plan (n x dof, after the start) must pass besides the metrics before the loop stops early on
// it: the exact clearance among furniture (the planner's success test there), which the padded body
// points of `settings.metrics` cannot judge. Called at the pre-termination checks only.
using PlanCheck = std::function<bool(const Trajectory&)>;
OmgLoopResult run_omg_loop(const ChompProblem& problem, const GraspRefiner* refiner, int hand_link,
                           const Eigen::VectorXd& q0, const Trajectory& goals, const std::vector<Trajectory>& tails,
                           const std::vector<int>& grasp_index, const Eigen::VectorXd& blend,
                           const OmgLoopSettings& settings, const WarmStart* warm = nullptr,
                           const PlanCheck* check = nullptr);

}  // namespace pickplan::omg
