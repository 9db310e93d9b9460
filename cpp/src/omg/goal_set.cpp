#include "pickplan/omg/goal_set.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <stdexcept>

#include "pickplan/core/errors.hpp"

namespace pickplan {

const char* to_string(GoalReason reason) {
  switch (reason) {
    case GoalReason::ok: return "ok";
    case GoalReason::unreachable: return "unreachable";
    case GoalReason::in_collision: return "in_collision";
    case GoalReason::standoff_unreachable: return "standoff_unreachable";
    case GoalReason::standoff_in_collision: return "standoff_in_collision";
    case GoalReason::approach_clearance: return "approach_clearance";
    case GoalReason::pregrasp_clearance: return "pregrasp_clearance";
    case GoalReason::duplicate: return "duplicate";
    case GoalReason::over_cap: return "over_cap";
  }
  throw std::invalid_argument("invalid goal reason " + std::to_string(static_cast<int>(reason)));
}

GoalSet build_goal_set(const IkSolver& ik, const CollisionChecker* checker, const CollisionChecker* hand_checker,
                       const std::vector<Transform>& hand_poses,
                       const Eigen::VectorXd& start, const GoalSetSettings& s,
                       const std::function<bool(const Eigen::VectorXd&)>& approach_ok, const Trajectory* seeds,
                       const std::function<bool(const Eigen::VectorXd&)>& pregrasp_ok) {
  const auto t0 = std::chrono::steady_clock::now();
  if (s.standoff_steps < 0 || s.standoff < 0 || s.max_goals < 1 || s.diversity < 0)
    throw std::invalid_argument("goal set settings: standoff, standoff_steps, diversity >= 0 and max_goals >= 1 required");
  require_finite("goal set settings: approach", s.approach.data(), 3);
  const bool world_approach = !s.approach.isZero();
  if (world_approach && std::abs(s.approach.norm() - 1.0) > 1e-6)
    throw std::invalid_argument("goal set settings: approach must be a unit vector or zero");
  const Robot& robot = ik.robot();
  robot.check_configuration(start.data(), start.size());
  // The checkers read the IK robot's configurations: they must describe a robot of the same size.
  if (checker) require_size("goal set: collision checker robot", robot.dof(), checker->robot().dof(), "joints");
  if (hand_checker) require_size("goal set: hand checker robot", robot.dof(), hand_checker->robot().dof(), "joints");
  const int d = robot.dof(), m = s.standoff_steps + 1;
  GoalSet out;
  out.reasons.assign(hand_poses.size(), GoalReason::over_cap);
  std::vector<Trajectory> tails;
  std::vector<int> index;
  std::unique_ptr<CollisionWorkspace> cws = checker ? std::make_unique<CollisionWorkspace>(*checker) : nullptr;
  auto collides = [&](const Eigen::VectorXd& q) { return checker && checker->in_collision(q.data(), *cws); };
  // The hand checker holds only the links the grasp pose places rigidly (hand, fingers): when
  // they collide, every arm configuration reaching this grasp collides too.
  std::unique_ptr<CollisionWorkspace> hws = hand_checker ? std::make_unique<CollisionWorkspace>(*hand_checker) : nullptr;
  auto hand_collides = [&](const Eigen::VectorXd& q) { return hand_checker && hand_checker->in_collision(q.data(), *hws); };
  auto too_close = [&](const Eigen::VectorXd& q) { return approach_ok && !approach_ok(q); };
  // The hand links' poses relative to the IK link (fingers as in `start`): a grasp whose hand
  // collides at the grasp or anywhere on its approach is rejected before any IK.
  std::vector<Transform> hand_relative;
  if (hand_checker) {
    RobotWorkspace fk(robot);
    robot.forward_kinematics(start.data(), fk);
    const Transform inv = fk.link_pose[ik.link()].inverse();
    for (const Transform& T : fk.link_pose) hand_relative.push_back(inv * T);
  }
  const Transform tip_inverse = ik.tip().inverse();
  auto free_hand_collides = [&](const Transform& ik_target) {
    const Transform link_pose = ik_target * tip_inverse;
    for (size_t l = 0; l < hand_relative.size(); ++l) hws->robot.link_pose[l] = link_pose * hand_relative[l];
    return hand_checker->in_collision_posed(*hws);
  };
  auto approach_pose = [&](size_t g, int k) {  // k = m - 1: the grasp; 0: the pre-grasp
    Transform pre = hand_poses[g];
    const Eigen::Vector3d axis = world_approach ? s.approach : Eigen::Vector3d(pre.R.col(2));
    pre.p -= s.standoff * static_cast<double>(m - 1 - k) / std::max(1, m - 1) * axis;
    return pre;
  };
  // Grasps are tried in a seeded random order until max_goals goals are kept: the kept set is a
  // uniform random choice of the feasible, diverse grasps, and the work stops when enough are found.
  std::vector<size_t> order(hand_poses.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::mt19937 rng(s.seed);
  std::shuffle(order.begin(), order.end(), rng);
  size_t tried_grasps = 0;
  for (; tried_grasps < order.size() && static_cast<int>(tails.size()) < s.max_goals; ++tried_grasps) {
    const size_t g = order[tried_grasps];
    if (hand_checker) {
      int k = m - 1;
      while (k >= 0 && !free_hand_collides(approach_pose(g, k))) --k;
      if (k >= 0) {
        out.reasons[g] = k == m - 1 ? GoalReason::in_collision : GoalReason::standoff_in_collision;
        continue;
      }
    }
    // Seeds in order (start first): the first solution that is collision-free and has a
    // feasible approach chain wins. Lazy, so reachable grasps cost one or two descents.
    GoalReason reason = GoalReason::unreachable;
    std::vector<Eigen::VectorXd> tried;
    for (int k = seeds ? -1 : 0; k < ik.settings().num_seeds; ++k) {
      const IkSolution sol = ik.solve(hand_poses[g], k < 0 ? Eigen::VectorXd(seeds->row(static_cast<long>(g)).transpose())
                                                            : ik.seed_configuration(k, start));
      if (!sol.converged) continue;
      bool seen = false;
      for (const auto& q : tried) seen = seen || (q - sol.q).cwiseAbs().maxCoeff() < ik.settings().duplicate_tolerance;
      if (seen) continue;
      tried.push_back(sol.q);
      if (static_cast<int>(tried.size()) > s.max_solutions) break;
      if (collides(sol.q)) {
        reason = GoalReason::in_collision;
        if (hand_collides(sol.q)) break;
        continue;
      }
      if (too_close(sol.q)) {
        reason = GoalReason::approach_clearance;
        continue;
      }
      Trajectory tail(m, d);
      tail.row(m - 1) = sol.q.transpose();
      bool ok = true;
      for (int k2 = m - 2; k2 >= 0 && ok; --k2) {
        const IkSolution step = ik.solve(approach_pose(g, k2), tail.row(k2 + 1).transpose());  // backed off along z
        if (!step.converged || (step.q.transpose() - tail.row(k2 + 1)).cwiseAbs().maxCoeff() > s.max_joint_jump) {
          ok = false;
          reason = GoalReason::standoff_unreachable;
        } else if (collides(step.q)) {
          ok = false;
          reason = GoalReason::standoff_in_collision;
        } else if (too_close(step.q)) {
          ok = false;
          reason = GoalReason::approach_clearance;
        } else {
          tail.row(k2) = step.q.transpose();
        }
      }
      if (ok && pregrasp_ok && !pregrasp_ok(tail.row(0).transpose())) {
        ok = false;
        reason = GoalReason::pregrasp_clearance;
      }
      if (ok) {
        // Diversity: a goal too close to one already kept is a duplicate.
        reason = GoalReason::ok;
        for (const Trajectory& kept : tails)
          if ((tail.row(m - 1) - kept.row(m - 1)).cwiseAbs().maxCoeff() < s.diversity) reason = GoalReason::duplicate;
        if (reason == GoalReason::ok) {
          tails.push_back(std::move(tail));
          index.push_back(static_cast<int>(g));
        }
        break;
      }
    }
    out.reasons[g] = reason;
  }
  for (size_t i = tried_grasps; i < order.size(); ++i) out.reasons[order[i]] = GoalReason::over_cap;  // never tried
  // Goals in input order (deterministic, independent of the trial order).
  std::vector<int> kept(tails.size());
  std::iota(kept.begin(), kept.end(), 0);
  std::sort(kept.begin(), kept.end(), [&](int a, int b) { return index[a] < index[b]; });
  out.goals.resize(kept.size(), d);
  for (size_t i = 0; i < kept.size(); ++i) {
    out.goals.row(i) = tails[kept[i]].row(m - 1);
    out.tails.push_back(tails[kept[i]]);
    out.grasp_index.push_back(index[kept[i]]);
  }
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace pickplan
