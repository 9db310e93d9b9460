#pragma once
// Goal sets: grasps in the world -> IK -> standoff approach chain -> collision filter ->
// diversity filter -> capped set. Every rejected grasp carries its reason.
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/ik.hpp"
#include "pickplan/geometry/collision.hpp"
#include "pickplan/omg/chomp.hpp"

namespace pickplan::omg {

// Why a grasp gave no goal (or ok: it did). The text forms are what Python and the plan files read.
enum class GoalReason {
  ok,
  unreachable,
  in_collision,
  standoff_unreachable,
  standoff_in_collision,
  approach_clearance,
  pregrasp_clearance,  // the pre-grasp (a place's pre-place) fails `pregrasp_ok`
  duplicate,           // closer than `diversity` to a goal already kept
  over_cap             // not tried: the cap was reached first
};
const char* to_string(GoalReason reason);

struct GoalSetSettings {
  double standoff = 0.08;       // m, pre-grasp distance back along the approach axis (hand +z)
  int standoff_steps = 4;       // waypoints from the pre-grasp to the grasp (the tail has steps + 1 rows)
  double max_joint_jump = 0.5;  // rad between consecutive tail configurations (continuity)
  double diversity = 0.1;       // rad (max-norm): goals closer than this to a kept goal are duplicates
  int max_goals = 30;           // cap, as in the paper's experiments (up to 100): grasps are tried
                                // in a seeded random order until this many goals are kept
  int max_solutions = 4;        // distinct IK solutions tried per grasp before giving up on it
  unsigned seed = 0;            // the trial order (so which goals are kept: a seeded, uniform subset)
  // World direction the hand moves in along the standoff (unit, or zero: the hand's own +z, a
  // grasp's approach). A place sets gravity: the held object comes down onto its support.
  Eigen::Vector3d approach = Eigen::Vector3d::Zero();
  // `approach_ok` is also asked at approach_substeps - 1 joint-linear points between consecutive tail
  // configurations: the success test interpolates the tail densely, and its clearance can dip between
  // them (1: the tail configurations alone).
  int approach_substeps = 1;
};

struct GoalSet {
  Trajectory goals;                 // G x dof grasp configurations
  std::vector<Trajectory> tails;    // per goal: (steps + 1) x dof, pre-grasp first, grasp last
  std::vector<int> grasp_index;     // input grasp of each goal
  std::vector<GoalReason> reasons;  // per input grasp
  double seconds = 0;
};

// hand_poses: world poses of the IK link for each grasp. `checker` may be null (no collision
// filter); `hand_checker` (optional) holds only the hand and finger links, for early rejection.
// `approach_ok` (optional): every tail configuration (pre-grasp .. grasp) must pass it (e.g. keep
// the clearance the success test demands of a plan's approach); failing grasps: approach_clearance.
// `seeds` (optional, one row per grasp): the first IK seed of each grasp, before the start and the
// spread (a replan seeds each grasp with its goal before the target moved).
// `pregrasp_ok` (optional): the pre-grasp, where the transit arrives, must pass it too (a place's
// pre-place keeps the transit's clearance); failing grasps: pregrasp_clearance. Checked inside the
// loop, so such a goal does not take a place under the cap.
GoalSet build_goal_set(const core::IkSolver& ik, const geometry::CollisionChecker* checker,
                       const geometry::CollisionChecker* hand_checker, const std::vector<core::Transform>& hand_poses,
                       const Eigen::VectorXd& start, const GoalSetSettings& settings = {},
                       const std::function<bool(const Eigen::VectorXd&)>& approach_ok = {},
                       const Trajectory* seeds = nullptr,
                       const std::function<bool(const Eigen::VectorXd&)>& pregrasp_ok = {});

}  // namespace pickplan::omg
