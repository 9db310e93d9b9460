#pragma once
// Inverse kinematics for a 6-D link pose: damped least squares (Levenberg-Marquardt with
// adaptive damping) inside the joint limits, from several seeds. Chosen over NLopt for speed:
// a converging solve takes ~10-20 iterations of one FK + one 6x6 solve (see pickplan-bench).
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"

namespace pickplan {

struct IkSettings {
  int max_iterations = 40;  // converging descents: median 8, 90 % <= 26; later seeds cover the rest (99.6 %)
  double position_tolerance = 1e-4;   // m
  double rotation_tolerance = 1e-3;   // rad
  double damping = 1e-2;              // initial Levenberg-Marquardt damping
  double max_step = 0.5;              // rad per iteration, so a step never jumps across the workspace
  int num_seeds = 24;                 // the start configuration plus a fixed, seeded spread (99.6 % on random poses)
  unsigned seed = 0;                  // for the spread of seeds
  double duplicate_tolerance = 0.05;  // rad: solutions closer than this (max-norm) are the same
  std::vector<bool> active;           // joints IK may move (empty = all)
};

struct IkSolution {
  Eigen::VectorXd q;
  double position_error = 0, rotation_error = 0;
  int iterations = 0;
  bool converged = false;
};

class IkSolver {
 public:
  // Solves for the pose of `link` (its frame, optionally offset by `tip` in the link frame).
  IkSolver(std::shared_ptr<const Robot> robot, int link, IkSettings settings = {}, const Transform& tip = {});

  const Robot& robot() const { return *robot_; }
  const IkSettings& settings() const { return settings_; }
  int link() const { return link_; }
  const Transform& tip() const { return tip_; }

  // One descent from `seed`; inactive joints keep the seed's values.
  IkSolution solve(const Transform& target, const Eigen::VectorXd& seed) const;
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

}  // namespace pickplan
