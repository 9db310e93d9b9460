#pragma once
// Inverse kinematics by damped least squares: the one IK solver of the library (goal sets, the
// pick-up NLP's seeds, the lift in execution). One descent (solve_ik) takes per-joint weights,
// joint limits with a margin, a full pose or a position target, and a fixed or adaptive
// (Levenberg-Marquardt) damping; IkSolver adds a fixed, seeded spread of start configurations.
// Written by hand rather than with a general NLP library for speed: a converging solve takes ~10-20 iterations of one
// FK + one 6x6 solve (see pickplan-bench).
#include <memory>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"

namespace pickplan::core {

enum class IkTask { pose, position };          // the target fixes the full pose | its position only
enum class IkDamping { adaptive, fixed };      // Levenberg-Marquardt: only decreases kept | every step kept
enum class IkStepNorm { max_abs, euclidean };  // the norm max_step bounds
// The rotation part of the error the steps reduce: angle * axis (the rotation vector) | sin(angle)
// * axis (half the sum of the columns' cross products). Equal near the target; they differ on the
// way, and where the target is out of reach they settle on different compromises (the pick-up
// seeds and the lift were tuned with sine_axis).
enum class IkRotationError { angle_axis, sine_axis };

// One descent. Each step is dq = W J^T (J W J^T + damping I)^-1 e, W = diag(weights), e the error
// (position; rotation of target * current^-1, see IkRotationError), shrunk to max_step and clamped into
// [lower + limit_margin, upper - limit_margin] for every joint with a weight above zero.
struct DlsSettings {
  IkTask task = IkTask::pose;
  IkRotationError rotation_error = IkRotationError::angle_axis;
  int max_iterations = 40;           // converging descents: median 8, 90 % <= 26; later seeds cover the rest (99.6 %)
  double position_tolerance = 1e-4;  // m: converged below this and rotation_tolerance
  double rotation_tolerance = 1e-3;  // rad (ignored for IkTask::position)
  IkDamping damping_schedule = IkDamping::adaptive;
  double damping = 1e-2;           // > 0, added to J W J^T's diagonal (adaptive: its start value)
  double damping_decrease = 0.3;   // adaptive: factor after a step that lowered the error
  double damping_increase = 10.0;  // adaptive: factor after a rejected step
  double min_damping = 1e-8;       // adaptive: bounds of the damping
  double max_damping = 1e4;
  double min_relative_decrease = 1e-3;  // a step lowering the squared error by less stalls
  int max_stalled_iterations = 8;       // stop after this many stalls in a row (a local minimum or a limit); 0: never
  double max_step = 0.5;                // rad (m for prismatic joints) per step: never jump across the workspace
  IkStepNorm step_norm = IkStepNorm::max_abs;
  double limit_margin = 0.0;    // moving joints stay this far inside their limits
  std::vector<double> weights;  // per joint, >= 0; 0 freezes a joint at the seed's value; empty: all 1
};

// The multi-start solver's settings: one descent's plus the spread of seeds.
struct IkSettings : DlsSettings {
  int num_seeds = 24;                 // the start configuration plus a fixed, seeded spread (99.6 % on random poses)
  unsigned seed = 0;                  // for the spread of seeds
  double duplicate_tolerance = 0.05;  // rad: solutions closer than this (max-norm) are the same
};

struct IkSolution {
  Eigen::VectorXd q;
  double position_error = 0, rotation_error = 0;  // m, rad (the angle) at q
  int iterations = 0;                             // steps computed
  bool converged = false;  // both errors below the tolerances (position only for IkTask::position)
};

// Throws std::invalid_argument naming the first setting out of range or a weights vector whose
// size is not robot.dof().
void validate(const DlsSettings& settings, const Robot& robot);

// One descent of the point `tip` (a pose in the frame of `link`) toward `target` from `seed`.
// Throws std::invalid_argument for a link out of range, a seed of the wrong size or not finite,
// a target not finite, or invalid settings. Not reaching the target is a result (.converged).
IkSolution solve_ik(const Robot& robot, int link, const Transform& tip, const Transform& target,
                    const Eigen::VectorXd& seed, const DlsSettings& settings);

class IkSolver {
 public:
  // Solves for the pose of `link` (its frame, optionally offset by `tip` in the link frame).
  IkSolver(std::shared_ptr<const Robot> robot, int link, IkSettings settings = {}, const Transform& tip = {});

  const Robot& robot() const { return *robot_; }
  const IkSettings& settings() const { return settings_; }
  int link() const { return link_; }
  const Transform& tip() const { return tip_; }

  // One descent from `seed` (solve_ik); frozen joints keep the seed's values.
  IkSolution solve(const Transform& target, const Eigen::VectorXd& seed) const;
  // One descent per target, each from the previous solution (the first from `seed`): a path.
  std::vector<IkSolution> solve_path(const std::vector<Transform>& targets, const Eigen::VectorXd& seed) const;
  // From `start` first, then the spread of seeds: every distinct converged solution, nearest to start first.
  std::vector<IkSolution> solve_all(const Transform& target, const Eigen::VectorXd& start) const;
  // The first converged solution (start, then the spread); .converged false when none.
  IkSolution solve_any(const Transform& target, const Eigen::VectorXd& start) const;
  // Seed k of solve_all's order: 0 is `start`, then the fixed spread (k < settings().num_seeds).
  Eigen::VectorXd seed_configuration(int k, const Eigen::VectorXd& start) const;
  // Pose error of q against target: (position m, rotation rad).
  std::pair<double, double> pose_error(const Eigen::VectorXd& q, const Transform& target) const;

 private:
  std::shared_ptr<const Robot> robot_;
  int link_;
  IkSettings settings_;
  Transform tip_;
  std::vector<Eigen::VectorXd> spread_;  // seeds in [0,1]^dof, scaled into the limits at use
};

// Rotation vector (axis * angle) of R, robust near 0 and pi.
Eigen::Vector3d rotation_log(const Eigen::Matrix3d& R);

}  // namespace pickplan::core
