#pragma once
// RRT-Connect (Kuffner and LaValle, ICRA 2000) in joint space on the FCL checker, with a goal set
// (the goal tree is rooted at every goal), path shortcutting, and the motion check every edge
// takes: states along a straight joint-space segment, spaced so that no point of the robot moves
// more than `resolution` metres between two checked states (MotionBound: a Lipschitz bound of
// the robot's points in the joint values, from its geometry's reach). Used as the seed CHOMP
// smooths in constrained spaces (shelves, bins) where a straight line is no start.
#include <chrono>
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "pickplan/geometry/collision.hpp"
#include "pickplan/omg/chomp.hpp"

namespace pickplan::omg {

// |x(q + dq) - x(q)| <= sum_j factor[j] |dq_j| for every point x of the robot's collision geometry.
class MotionBound {
 public:
  explicit MotionBound(const geometry::CollisionChecker& checker);
  const Eigen::VectorXd& factors() const { return factors_; }  // m per unit of each joint
  double bound(const double* a, const double* b) const;        // metres, for the segment a -> b
  // Checked states a segment needs so that consecutive ones lie within `resolution` (>= 1).
  int steps(const double* a, const double* b, double resolution) const;

 private:
  Eigen::VectorXd factors_;
};

struct RrtSettings {
  double range = 0.5;            // largest extension (rad, Euclidean over the active joints)
  double resolution = 0.01;      // m: largest motion of any robot point between checked states
  long max_iterations = 200000;  // samples before giving up
  double time_limit = 1.0;       // s (wall clock) before giving up
  std::uint64_t seed = 0;
  double goal_bias = 0.05;  // fraction of samples drawn at a goal (the start tree's extensions)
  // The motion check proves a segment keeps a clearance (10 um) by conservative advancement (a state
  // whose clearance is d proves the states around it no point can have moved d from; midpoints of the
  // unproved intervals, coarse to fine) instead of sampling it every `resolution` m, which lets a
  // finger graze an obstacle between samples.
  bool certified = true;
  std::vector<bool> active;  // joints that move (empty: all); the others keep the start's value
};

enum class RrtStatus { solved, timeout, iterations, invalid_start, invalid_goals };

struct RrtResult {
  RrtStatus status = RrtStatus::timeout;
  Trajectory path;  // start ... goal (rows), when solved
  int goal = -1;    // row of the goal set reached
  long iterations = 0, checks = 0, nodes = 0;
  double seconds = 0;
};

class MotionPlanner {
 public:
  // The checker decides validity (with its allowed pairs, margin and self-collision settings).
  MotionPlanner(const geometry::CollisionChecker& checker, RrtSettings settings = {});
  const RrtSettings& settings() const { return settings_; }
  const geometry::CollisionChecker& checker() const { return checker_; }
  const MotionBound& bound() const { return bound_; }

  // Throws std::invalid_argument for a start or goals of the wrong size or outside the limits.
  RrtResult rrt_connect(const Eigen::VectorXd& start, const Trajectory& goals) const;
  // Random shortcuts between points on the path (then dropping vertices a straight segment
  // skips); every new segment passes the motion check. Deterministic for a seed. A shortcut that
  // would shorten the path by less than `min_gain` times its length is not checked nor taken.
  Trajectory shortcut(const Trajectory& path, int attempts, std::uint64_t seed, double min_gain = 0.0) const;
  // The motion check: true when every checked state of a -> b is free (a itself is not checked),
  // or, `certified`, when the whole continuous motion is proved free.
  bool motion_valid(const double* a, const double* b, geometry::CollisionWorkspace& ws, long* checks = nullptr) const;
  bool motion_certified(const double* a, const double* b, geometry::CollisionWorkspace& ws,
                        long* checks = nullptr) const;
  // The first segment (row i -> i + 1) that fails the motion check, or -1; the first row is checked too.
  int first_invalid_segment(const Trajectory& path) const;

 private:
  const geometry::CollisionChecker& checker_;
  RrtSettings settings_;
  MotionBound bound_;
  std::vector<int> active_;  // active joint indices
};

}  // namespace pickplan::omg
