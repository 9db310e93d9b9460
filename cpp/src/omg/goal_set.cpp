#include "pickplan/omg/goal_set.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <numeric>
#include <random>
#include <stdexcept>

#include "pickplan/core/errors.hpp"

namespace pickplan::omg {

const char* to_string(GoalReason reason) {
  switch (reason) {
    case GoalReason::ok:
      return "ok";
    case GoalReason::unreachable:
      return "unreachable";
    case GoalReason::in_collision:
      return "in_collision";
    case GoalReason::standoff_unreachable:
      return "standoff_unreachable";
    case GoalReason::standoff_in_collision:
      return "standoff_in_collision";
    case GoalReason::approach_clearance:
      return "approach_clearance";
    case GoalReason::pregrasp_clearance:
      return "pregrasp_clearance";
    case GoalReason::duplicate:
      return "duplicate";
    case GoalReason::over_cap:
      return "over_cap";
  }
  throw std::invalid_argument("invalid goal reason " + std::to_string(static_cast<int>(reason)));
}

namespace {

// One goal-set build: the checkers' workspaces and what every grasp's trial reads.
class GoalSetBuilder {
 public:
  GoalSetBuilder(const core::IkSolver& ik, const geometry::CollisionChecker* checker,
                 const geometry::CollisionChecker* hand_checker, const std::vector<core::Transform>& hand_poses,
                 const Eigen::VectorXd& start, const GoalSetSettings& s,
                 const std::function<bool(const Eigen::VectorXd&)>& approach_ok, const Trajectory* seeds,
                 const std::function<bool(const Eigen::VectorXd&)>& pregrasp_ok)
      : ik_(ik),
        checker_(checker),
        hand_checker_(hand_checker),
        hand_poses_(hand_poses),
        start_(start),
        s_(s),
        approach_ok_(approach_ok),
        seeds_(seeds),
        pregrasp_ok_(pregrasp_ok),
        d_(ik.robot().dof()),
        m_(s.standoff_steps + 1),
        world_approach_(!s.approach.isZero()),
        cws_(checker ? std::make_unique<geometry::CollisionWorkspace>(*checker) : nullptr),
        hws_(hand_checker ? std::make_unique<geometry::CollisionWorkspace>(*hand_checker) : nullptr),
        tip_inverse_(ik.tip().inverse()) {
    // The hand links' poses relative to the IK link (fingers as in `start`): a grasp whose hand
    // collides at the grasp or anywhere on its approach is rejected before any IK.
    if (hand_checker) {
      const core::Robot& robot = ik.robot();
      core::RobotWorkspace fk(robot);
      robot.forward_kinematics(start.data(), fk);
      const core::Transform inv = fk.link_pose[ik.link()].inverse();
      for (const core::Transform& T : fk.link_pose) hand_relative_.push_back(inv * T);
    }
  }

  int rows() const { return m_; }

  // Grasp g's reason, its tail (pre-grasp first) appended to tails when kept.
  GoalReason try_grasp(size_t g, std::vector<Trajectory>& tails) const {
    if (hand_checker_) {
      int k = m_ - 1;
      while (k >= 0 && !free_hand_collides(approach_pose(g, k))) --k;
      if (k >= 0) return k == m_ - 1 ? GoalReason::in_collision : GoalReason::standoff_in_collision;
    }
    // Seeds in order (start first): the first solution that is collision-free and has a
    // feasible approach chain wins. Lazy, so reachable grasps cost one or two descents.
    GoalReason reason = GoalReason::unreachable;
    std::vector<Eigen::VectorXd> tried;
    for (int k = seeds_ ? -1 : 0; k < ik_.settings().num_seeds; ++k) {
      const core::IkSolution sol =
          ik_.solve(hand_poses_[g], k < 0 ? Eigen::VectorXd(seeds_->row(static_cast<long>(g)).transpose())
                                          : ik_.seed_configuration(k, start_));
      if (!sol.converged) continue;
      bool seen = false;
      for (const auto& q : tried) seen = seen || (q - sol.q).cwiseAbs().maxCoeff() < ik_.settings().duplicate_tolerance;
      if (seen) continue;
      tried.push_back(sol.q);
      if (static_cast<int>(tried.size()) > s_.max_solutions) break;
      if (collides(sol.q)) {
        reason = GoalReason::in_collision;
        if (hand_collides(sol.q)) break;
        continue;
      }
      if (too_close(sol.q)) {
        reason = GoalReason::approach_clearance;
        continue;
      }
      Trajectory tail(m_, d_);
      reason = approach_tail(g, sol.q, tail);
      if (reason != GoalReason::ok) continue;
      // Diversity: a goal too close to one already kept is a duplicate.
      for (const Trajectory& kept : tails)
        if ((tail.row(m_ - 1) - kept.row(m_ - 1)).cwiseAbs().maxCoeff() < s_.diversity) reason = GoalReason::duplicate;
      if (reason == GoalReason::ok) tails.push_back(std::move(tail));
      break;
    }
    return reason;
  }

 private:
  bool collides(const Eigen::VectorXd& q) const { return checker_ && checker_->in_collision(q.data(), *cws_); }
  // The hand checker holds only the links the grasp pose places rigidly (hand, fingers): when
  // they collide, every arm configuration reaching this grasp collides too.
  bool hand_collides(const Eigen::VectorXd& q) const {
    return hand_checker_ && hand_checker_->in_collision(q.data(), *hws_);
  }
  bool too_close(const Eigen::VectorXd& q) const { return approach_ok_ && !approach_ok_(q); }
  // Whether a joint-linear point strictly between a and b fails `approach_ok` (approach_substeps).
  bool too_close_between(const Eigen::VectorXd& a, const Eigen::VectorXd& b) const {
    for (int i = 1; approach_ok_ && i < s_.approach_substeps; ++i) {
      const double t = static_cast<double>(i) / s_.approach_substeps;
      if (!approach_ok_(((1.0 - t) * a + t * b).eval())) return true;
    }
    return false;
  }
  bool free_hand_collides(const core::Transform& ik_target) const {
    const core::Transform link_pose = ik_target * tip_inverse_;
    for (size_t l = 0; l < hand_relative_.size(); ++l) hws_->robot.link_pose[l] = link_pose * hand_relative_[l];
    return hand_checker_->in_collision_posed(*hws_);
  }
  core::Transform approach_pose(size_t g, int k) const {  // k = m - 1: the grasp; 0: the pre-grasp
    core::Transform pre = hand_poses_[g];
    const Eigen::Vector3d axis = world_approach_ ? s_.approach : Eigen::Vector3d(pre.R.col(2));
    pre.p -= s_.standoff * static_cast<double>(m_ - 1 - k) / std::max(1, m_ - 1) * axis;
    return pre;
  }
  // The tail from the grasp configuration q back along the approach to the pre-grasp, each step
  // by IK from the one after it; ok, or why the chain fails.
  GoalReason approach_tail(size_t g, const Eigen::VectorXd& q, Trajectory& tail) const {
    tail.row(m_ - 1) = q.transpose();
    for (int k2 = m_ - 2; k2 >= 0; --k2) {
      const core::IkSolution step =
          ik_.solve(approach_pose(g, k2), tail.row(k2 + 1).transpose());  // backed off along z
      if (!step.converged || (step.q.transpose() - tail.row(k2 + 1)).cwiseAbs().maxCoeff() > s_.max_joint_jump)
        return GoalReason::standoff_unreachable;
      if (collides(step.q)) return GoalReason::standoff_in_collision;
      if (too_close(step.q) || too_close_between(step.q, tail.row(k2 + 1).transpose()))
        return GoalReason::approach_clearance;
      tail.row(k2) = step.q.transpose();
    }
    if (pregrasp_ok_ && !pregrasp_ok_(tail.row(0).transpose())) return GoalReason::pregrasp_clearance;
    return GoalReason::ok;
  }

  const core::IkSolver& ik_;
  const geometry::CollisionChecker* checker_;
  const geometry::CollisionChecker* hand_checker_;
  const std::vector<core::Transform>& hand_poses_;
  const Eigen::VectorXd& start_;
  const GoalSetSettings& s_;
  const std::function<bool(const Eigen::VectorXd&)>& approach_ok_;
  const Trajectory* seeds_;
  const std::function<bool(const Eigen::VectorXd&)>& pregrasp_ok_;
  const int d_, m_;
  const bool world_approach_;
  std::unique_ptr<geometry::CollisionWorkspace> cws_, hws_;
  std::vector<core::Transform> hand_relative_;
  const core::Transform tip_inverse_;
};

void check_goal_set_inputs(const core::IkSolver& ik, const geometry::CollisionChecker* checker,
                           const geometry::CollisionChecker* hand_checker, const Eigen::VectorXd& start,
                           const GoalSetSettings& s) {
  if (s.standoff_steps < 0 || s.standoff < 0 || s.max_goals < 1 || s.diversity < 0 || s.approach_substeps < 1)
    throw std::invalid_argument(
        "goal set settings: standoff, standoff_steps, diversity >= 0 and max_goals >= 1, approach_substeps >= 1 "
        "required");
  core::require_finite("goal set settings: approach", s.approach.data(), 3);
  if (!s.approach.isZero() && std::abs(s.approach.norm() - 1.0) > 1e-6)
    throw std::invalid_argument("goal set settings: approach must be a unit vector or zero");
  const core::Robot& robot = ik.robot();
  robot.check_configuration(start.data(), start.size());
  // The checkers read the IK robot's configurations: they must describe a robot of the same size.
  if (checker) core::require_size("goal set: collision checker robot", robot.dof(), checker->robot().dof(), "joints");
  if (hand_checker)
    core::require_size("goal set: hand checker robot", robot.dof(), hand_checker->robot().dof(), "joints");
}

}  // namespace

GoalSet build_goal_set(const core::IkSolver& ik, const geometry::CollisionChecker* checker,
                       const geometry::CollisionChecker* hand_checker, const std::vector<core::Transform>& hand_poses,
                       const Eigen::VectorXd& start, const GoalSetSettings& s,
                       const std::function<bool(const Eigen::VectorXd&)>& approach_ok, const Trajectory* seeds,
                       const std::function<bool(const Eigen::VectorXd&)>& pregrasp_ok) {
  const auto t0 = std::chrono::steady_clock::now();
  check_goal_set_inputs(ik, checker, hand_checker, start, s);
  const GoalSetBuilder builder(ik, checker, hand_checker, hand_poses, start, s, approach_ok, seeds, pregrasp_ok);
  const int d = ik.robot().dof(), m = builder.rows();
  GoalSet out;
  out.reasons.assign(hand_poses.size(), GoalReason::over_cap);
  std::vector<Trajectory> tails;
  std::vector<int> index;
  // Grasps are tried in a seeded random order until max_goals goals are kept: the kept set is a
  // uniform random choice of the feasible, diverse grasps, and the work stops when enough are found.
  std::vector<size_t> order(hand_poses.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::mt19937 rng(s.seed);
  std::shuffle(order.begin(), order.end(), rng);
  size_t tried_grasps = 0;
  for (; tried_grasps < order.size() && static_cast<int>(tails.size()) < s.max_goals; ++tried_grasps) {
    const size_t g = order[tried_grasps];
    out.reasons[g] = builder.try_grasp(g, tails);
    if (out.reasons[g] == GoalReason::ok) index.push_back(static_cast<int>(g));
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

}  // namespace pickplan::omg
