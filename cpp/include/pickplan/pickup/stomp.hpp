#pragma once
// STOMP (Kalakrishnan et al., ICRA 2011) refinement of a discretised arm motion, used on the
// intervals [0, T1] and [T2, T] of a pick-up trajectory (Thakar et al., Sec. V-B): the polynomial
// solution may wander there, STOMP smooths it while avoiding obstacles. The first two and the last
// two waypoints are held, so positions and (finite-difference) velocities at the interval ends --
// where the grasping motion joins -- are unchanged; joint position and rate limits are penalised
// during the search and the returned trajectory is the best iterate that satisfies them.
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {

struct StompSettings {
  int iterations = 40;
  int rollouts = 12;
  double noise_stddev = 0.1;     // scales the smooth exploration noise N(0, R^-1)
  double temperature = 10.0;     // h of the per-timestep softmax
  double control_weight = 1.0;   // weight of the smoothness (squared acceleration) cost
  double obstacle_weight = 1e3;  // weight of the hinge obstacle cost per waypoint
  double limit_weight = 1e3;     // weight of the joint position / rate limit hinge costs
  double margin = 0.02;          // m, obstacle clearance wanted
  unsigned seed = 0;
};

struct StompResult {
  Eigen::MatrixXd q;                                    // (N, dof) refined waypoints (base columns unchanged)
  double initial_cost = 0, final_cost = 0;              // total cost
  double initial_smoothness = 0, final_smoothness = 0;  // sum of squared arm accelerations
  double max_rate = 0;                                  // max |finite-difference arm joint rate|, rad/s
  double min_clearance = 0;                             // min sphere clearance over the waypoints, m
  bool limits_ok = false;                               // joint position and rate limits hold at every waypoint
  int iterations = 0;
  double seconds = 0;
};

// Q: (N >= 5, dof) waypoints at spacing dt > 0; columns 0-2 the base (not changed), the rest the arm.
// Throws std::invalid_argument on bad shapes.
StompResult stomp_refine(const core::Robot& robot, const Eigen::MatrixXd& Q, double dt,
                         const Eigen::VectorXd& arm_rate_limits, const std::vector<BodySphere>& spheres,
                         const std::vector<SphereObstacle>& obstacles, const StompSettings& settings = {});

}  // namespace pickplan::pickup
