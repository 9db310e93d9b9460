#pragma once
// The paper's trajectory metrics (Sec. IV-A) on a densely interpolated trajectory.
#include <cstdint>
#include <limits>

#include "pickplan/omg/chomp.hpp"

namespace pickplan::omg {

struct MetricSettings {
  int steps = 200;                  // dense interpolation, start included
  double collision_padding = 0.05;  // "collision": sum of c(d) of points closer than this
  double epsilon = 0.2;             // padding of the cost c(d) summed by "collision"
  double clearance = 0.05;          // collision-free: every point at least this far from objects
  double table_clearance = 0.0;     // ... and this far from the table (grasps sit close to it)
  // The support surface: the links in support_link_mask (bit = link index: the fingers) may touch
  // the table down to support_tolerance inside it (a grasp of a thin object rests its fingertips on
  // it); every other link keeps table_clearance.
  std::uint64_t support_link_mask = 0;
  double support_tolerance = 0.0;
  int tail_waypoints = 0;              // the last waypoints (the standoff approach into the clutter,
  double tail_clearance = 0.01;        //   the goal set checks it) need only this clearance
  double smoothness_threshold = 30.0;  // planning success needs smoothness below this
  std::uint64_t exclude_mask = 0;      // objects not counted (the target)
  // The transit (before the tail) keeps at least this from the excluded objects (the target): the arm
  // reaching into a shelf must not sweep through what it will grasp. -inf: not measured (the paper's test).
  double transit_target_clearance = -std::numeric_limits<double>::infinity();
};

struct TrajectoryMetrics {
  double smoothness = 0;  // f_prior of the planned waypoints (dt of the problem)
  double collision = 0;
  double min_clearance = 0;        // to non-excluded objects (not the table); capped at the largest of
  double min_table_clearance = 0;  // epsilon and the clearances (farther is not measured)
  bool collision_free = false;
  bool success = false;  // collision-free and smooth enough
};

// `metrics` of a trajectory a check beyond them found in collision (the caller's exact one: body points
// sample a finger's surface to 1.7 cm): neither collision-free nor a success.
inline TrajectoryMetrics marked_in_collision(TrajectoryMetrics metrics) {
  metrics.collision_free = metrics.success = false;
  return metrics;
}

// Linear interpolation of [q0; xi] to `steps` configurations (rows).
Trajectory interpolate(const Eigen::VectorXd& q0, const Trajectory& xi, int steps);

// Smallest distance (up to `cap`) of the problem's body points at configuration q to the objects
// outside `exclude_mask` (the table left out), measured as evaluate_trajectory measures it.
double object_clearance(const ChompProblem& problem, const double* q, std::uint64_t exclude_mask, double cap,
                        core::RobotWorkspace& ws);

// stop_at_failure: return at the first reason the trajectory cannot succeed (too rough, or a dense
// step short of its clearance); success is then exact but the other metrics are partial.
TrajectoryMetrics evaluate_trajectory(const ChompProblem& problem, const Eigen::VectorXd& q0, const Trajectory& xi,
                                      const MetricSettings& settings, bool stop_at_failure = false);

}  // namespace pickplan::omg
