#pragma once
// CHOMP trajectory optimization with the goal-set projection (OMG paper Sec. III-A..C).
//
// xi = (q_1 .. q_n), q_0 fixed. f_prior = 1/2 sum_t |(q_t - q_{t-1}) / dt|^2 = 1/2 |K xi + e|^2.
// f_obstacle = sum_t sum_u c(x_u(q_t)) |x_u(q_t) - x_u(q_{t-1})| / dt: the cost of body point u
// weighted by its workspace speed (eq. 4; like f_prior, the Riemann sum divided by dt). Its exact gradient is the
// discrete form of CHOMP's functional gradient (velocity-orthogonal projection of grad c plus the curvature term).
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/geometry/sdf.hpp"

namespace pickplan::omg {

using Trajectory = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;  // n x dof

struct BodyPoints {
  std::vector<int> link;      // link index of each point
  geometry::Vertices points;  // N x 3, link frame
  int size() const { return static_cast<int>(link.size()); }
};

struct ChompSettings {
  int n = 30;                      // waypoints after the fixed start
  double duration = 3.0;           // seconds; dt = duration / n (0.1 s at n = 30)
  double lambda = 0.1;             // smoothness weight in f_obstacle + lambda f_prior (eq. 2)
  double lambda_growth = 1.02;     // lambda_i = lambda * growth^i: smoothness gains weight as iterations go
  double step_size = 0.1;          // 1 / eta_motion in the covariant update (eq. 6)
  double epsilon = 0.2;            // obstacle padding (m)
  int top_k = 500;                 // only the k largest obstacle terms contribute (0 = all)
  double clip_gradient = 10.0;     // element-wise clip of the obstacle gradient (0 = none)
  int joint_limit_steps = 10;      // smooth projections back inside the joint limits
  int obstacle_tail = 0;           // last waypoints whose obstacle cost is ignored (the standoff approach)
  std::uint64_t exclude_mask = 0;  // SceneSdf objects ignored by the obstacle cost (e.g. the target)
  bool link_culling = true;        // skip a link's points when its bounding sphere is beyond epsilon (exact)
  std::vector<bool> active;        // joints the optimizer moves (empty = all); others stay at q_0's value
};

struct ObjectiveTerms {
  double obstacle = 0, prior = 0, total = 0;
  int colliding_points = 0;  // terms with negative signed distance
};

class ChompProblem;

// Per-call scratch: sized once, reused every iteration (hot loops do not allocate).
struct ChompWorkspace {
  explicit ChompWorkspace(const ChompProblem& problem);
  std::vector<core::RobotWorkspace> fk;                                 // n + 1 link-pose sets (start included)
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> x, grad_d;  // (n+1)*N points, SDF gradients
  Eigen::VectorXd d;                                                    // (n+1)*N distances
  std::vector<double> term;                                             // n*N obstacle terms
  std::vector<int> order;  // candidate term indices for the top-k selection
  std::vector<char> live;  // (n+1) x groups: 1 distances evaluated, 2 points only, 0 culled
  Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor> wrench;  // (n+1) x groups: force, moment
  std::vector<int> loaded;                                           // wrench rows touched this evaluation
  Trajectory grad, u;                                                // gradient and A^-1 gradient
};

struct StepInfo {
  ObjectiveTerms before;  // objective at the trajectory the step started from
  double goal_error = 0;  // max |xi tail - goal| after the step (0 up to rounding)
  int limit_projections = 0;
};

// How an optimize() run ended. Bad input throws instead; a fixed iteration count always finishes.
enum class ChompStatus { ok };

struct ChompResult {
  Trajectory xi;
  std::vector<double> objective;  // per iteration, before each step
  ObjectiveTerms final_terms;
  int iterations = 0;
  ChompStatus status = ChompStatus::ok;
  double seconds = 0;
};

// Body points of one link, contiguous in BodyPoints, with a bounding sphere in the link frame.
struct LinkGroup {
  int link = 0, begin = 0, end = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0;
};

class ChompProblem {
 public:
  ChompProblem(std::shared_ptr<const core::Robot> robot, std::shared_ptr<const geometry::SceneSdf> scene,
               BodyPoints body, ChompSettings settings);

  const core::Robot& robot() const { return *robot_; }
  const geometry::SceneSdf& scene() const { return *scene_; }
  const BodyPoints& body() const { return body_; }
  const std::vector<LinkGroup>& groups() const { return groups_; }
  // Whether the objects and the table can come within epsilon of the group's points at the
  // link pose in fk (sound lower bounds over its bounding sphere: culling never changes a cost).
  struct GroupReach {
    bool objects, table;
    bool any() const { return objects || table; }
  };
  GroupReach group_reach(const core::RobotWorkspace& fk, const LinkGroup& group) const;
  const ChompSettings& settings() const { return settings_; }
  double dt() const { return dt_; }

  // f_prior and its gradient (n x dof) for xi with start q0.
  double prior(const Trajectory& xi, const Eigen::VectorXd& q0, Trajectory* grad) const;
  // f_obstacle over the top-k terms and its gradient (accumulated into *grad when given).
  ObjectiveTerms obstacle(const Trajectory& xi, const Eigen::VectorXd& q0, Trajectory* grad, ChompWorkspace& ws) const;
  // f_motion = f_obstacle + lambda_i f_prior at iteration i, with its gradient.
  ObjectiveTerms objective(const Trajectory& xi, const Eigen::VectorXd& q0, int iteration, Trajectory* grad,
                           ChompWorkspace& ws) const;

  // One covariant step. With `goal` (m x dof, m >= 1), CHOMP-Proj (eq. 7-8): the last m
  // waypoints are projected onto `goal` exactly. Without it, plain CHOMP with a fixed end.
  StepInfo step(Trajectory& xi, const Eigen::VectorXd& q0, const Trajectory* goal, int iteration,
                ChompWorkspace& ws) const;
  // `iterations` steps toward a fixed goal (tail); records the objective per iteration.
  ChompResult optimize(Trajectory xi, const Eigen::VectorXd& q0, const Trajectory& goal, int iterations) const;

  // A^-1 applied to each column of v (n x dof), by the banded (tridiagonal) Cholesky factor.
  void solve_A(const Trajectory& v, Trajectory& out) const;
  // A itself (n x n, unscaled by joints) for tests.
  Eigen::MatrixXd A_matrix() const;

  void check_trajectory(const Trajectory& xi, const Eigen::VectorXd& q0) const;

  // Goal-cost estimates of OMG Sec. III-D: for each goal g (row), the tail from xi(t_i),
  // t_i = iteration / horizon, to g at constant velocity, and its f = f_obstacle + lambda_i
  // f_prior (obstacle terms on every time_stride-th waypoint and point_stride-th body point,
  // rescaled, so estimates can be subsampled). Unnormalized; out has goals.rows() entries.
  void goal_costs(const Trajectory& xi, const Eigen::VectorXd& q0, int iteration, int horizon, const Trajectory& goals,
                  int time_stride, int point_stride, double* out, ChompWorkspace& ws) const;

 private:
  const Eigen::MatrixXd& projector(int m) const;  // M = A^-1 C^T (C A^-1 C^T)^-1 for a tail of m rows
  void project_limits(Trajectory& xi, int m, ChompWorkspace& ws, StepInfo& info) const;
  void mask_inactive(Trajectory& g) const;
  void transform_points(const core::RobotWorkspace& fk, const LinkGroup& group, double* x_world) const;
  // obstacle()'s phases, up to waypoint last_t: points and distances where a group may be near;
  // the charged terms (ws.term at the indices ws.order lists, top-k kept); their gradient into g.
  void obstacle_distances(const Trajectory& xi, const Eigen::VectorXd& q0, int last_t, ChompWorkspace& ws) const;
  void obstacle_terms(int last_t, ChompWorkspace& ws, ObjectiveTerms& out) const;
  void obstacle_gradient(ChompWorkspace& ws, Trajectory& g) const;

  std::shared_ptr<const core::Robot> robot_;
  std::shared_ptr<const geometry::SceneSdf> scene_;
  BodyPoints body_;
  std::vector<LinkGroup> groups_;
  std::vector<int> group_of_;  // body point -> its group
  ChompSettings settings_;
  double dt_;
  Eigen::VectorXd chol_diag_, chol_sub_;     // A = L L^T, L lower bidiagonal
  std::vector<Eigen::MatrixXd> projectors_;  // by tail length m = 1..min(n, 16) (chomp.cpp), built on construction
};

// CHOMP workspace cost c(d) and its derivative (Ratliff et al.).
inline double chomp_cost(double d, double eps, double* dcost) {
  if (d < 0) {
    if (dcost) *dcost = -1.0;
    return -d + 0.5 * eps;
  }
  if (d < eps) {
    if (dcost) *dcost = (d - eps) / eps;
    return 0.5 * (d - eps) * (d - eps) / eps;
  }
  if (dcost) *dcost = 0.0;
  return 0.0;
}

}  // namespace pickplan::omg
