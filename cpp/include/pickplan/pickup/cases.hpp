#pragma once
// The test cases of Thakar et al. Sec. VI on assets/mobile_ur5.urdf, defined once here and used
// by the benchmark, the C++ tests and (through the bindings) python/pickplan/pickup/cases.py.
//   start (0, 0, pi/6), goal (8, 0, 0) with tolerance 0.5 m / pi/4, part at (3, 4) on a pedestal,
//   part yaw 0, pi/4, pi/2, 0, pi/4, pi/2 for cases 1..6;
//   cases 1-3: top grasp (tool z down, fingers closing across the part, n_g along the part's x);
//   cases 4-6: side grasp (tool z = n_g = the part's x axis, horizontal; fingers closing horizontally).
// Base speed <= 2 m/s, arm joint rates <= arm_rate (pi rad/s in the paper).
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {

struct PaperCaseOptions {
  double gamma = 0.96;
  double arm_rate = 3.141592653589793;
  bool obstacles = true;  // pedestal under the part and a pillar beside the route
  double part_z = 0.5;    // grasp height (part centre), m
};

// How the part is grasped: top (tool z down, fingers closing across the part's x, n_g along it) or
// side (tool z = n_g = the part's x axis, horizontal; fingers closing horizontally).
enum class GraspKind { top, side };

// Sets the grasp pose, approach direction n_g and grasping-area centre of a part at `position`
// (grasp point, world) with yaw `yaw` about the world z axis.
void set_part_grasp(PickupProblem& pb, GraspKind kind, double yaw, const Eigen::Vector3d& position);

// The problem of case 1..6 (throws std::invalid_argument otherwise). The robot must be mobile_ur5.
PickupProblem paper_case(const core::Robot& robot, int case_id, const RhoPoly& rho, const PaperCaseOptions& opt = {});
// A monotone (non-increasing in S_g, non-decreasing in S_c) Bernstein surface on
// S_g in [0.05, 1.2] m/s, S_c in [0.05, 0.15] m/s for tests and benchmarks; `shift` moves it up/down.
RhoPoly example_rho(double shift = 0.0);

// Independent check of a planned trajectory by dense re-sampling (n instants over [0, T]).
struct PickupMetrics {
  double pose_error_position = 0;       // |p_tool(T2) - p_grasp|, m
  double pose_error_orientation = 0;    // rotation angle between R_tool(T2) and R_grasp, rad
  double nonholonomic_mean = 0;         // mean |x' sin phi - y' cos phi| over [0, T], m/s
  double nonholonomic_drift = 0;        // integral of |x' sin phi - y' cos phi| dt over [0, T], m
  double nonholonomic_max = 0;          // m/s
  double joint_limit_violation = 0;     // max over arm joints and time, rad
  double joint_rate_max = 0;            // max |q_i'| over arm joints, rad/s
  double base_speed_max = 0;            // m/s
  double base_speed_grasp_mean = 0;     // mean base speed during [T1, T2], m/s
  double gripper_speed_grasp_mean = 0;  // mean |J q'| of the tool during [T1, T2], m/s
  double velocity_error_max = 0;        // max |J q' - S_g n_g| during [T1, T2], m/s
  double min_clearance = 0;             // min signed sphere distance to obstacles, m (inf: none)
  double goal_position_error = 0;       // |(x, y)(T) - goal|, m
  double success_probability = 0;       // rho(S_g, S_c)
};
PickupMetrics evaluate_pickup(const core::Robot& robot, const PickupProblem& pb, const PickupResult& res, int n = 2001);

}  // namespace pickplan::pickup
