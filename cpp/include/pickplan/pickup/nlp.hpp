#pragma once
// Time-optimal pick-up on the move (Thakar et al., Sec. III and V): a 9-DOF mobile manipulator
// whose DOFs are polynomials in time picks up a part while driving from a start to a goal.
// The NLP is solved by Ipopt (C++ TNLP interface, exact first and second derivatives:
// PickupSettings::hessian) in five stages of successive refinement, each seeded by the previous.
//
// THREAD SAFETY: Ipopt 3.11 with MUMPS is NOT thread-safe. Never run two solves at once in one
// process; run independent solves in separate processes (the Python layer does).
//
// Decision variables x = [polynomial coefficients | s1, s2, T | S_g, S_c]: each DOF is a polynomial
// P_i(s) in normalised time s = t / T (q_i(t) = P_i(t / T), the paper's polynomial in t with its
// coefficients scaled by T^k), and T1 = s1 T, T2 = s2 T with 0 <= s1 <= s2 <= 1.
#include <array>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/core/transform.hpp"
#include "pickplan/pickup/options.hpp"
#include "pickplan/pickup/poly_traj.hpp"

namespace pickplan::pickup {

// rho_sigma(S_g, S_c) as a tensor-product Bernstein polynomial on [sg_lo, sg_hi] x [sc_lo, sc_hi]
// (the RhoSurface format of the meta-model: coeffs[i, j] multiplies B_i(u) B_j(v)).
struct RhoPoly {
  Eigen::MatrixXd coeffs;  // (deg_g + 1) x (deg_c + 1)
  double sg_lo = 0.0, sg_hi = 1.0, sc_lo = 0.0, sc_hi = 1.0;
  void validate() const;  // throws std::invalid_argument
  double value(double s_g, double s_c) const;
  Eigen::Vector2d gradient(double s_g, double s_c) const;  // (d/dS_g, d/dS_c)
  Eigen::Matrix2d hessian(double s_g, double s_c) const;
  // The largest S_g with rho >= gamma for some S_c in [sc_a, sc_b] (16 S_c grid points): the last
  // crossing of gamma on a 64-point S_g grid, refined by bisection (sg_hi when rho >= gamma there).
  // NaN when no grid point reaches gamma (the success-probability threshold is unattainable).
  double sg_upper_bound(double gamma, double sc_a, double sc_b) const;
};

struct SphereObstacle {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.1;
};

struct BodySphere {  // a sphere fixed on a robot link (center in the link frame)
  int link = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
  double radius = 0.05;
};

// What to plan. The first three DOFs of the robot must be the planar base (x, y, yaw).
struct PickupProblem {
  Eigen::Vector3d start = Eigen::Vector3d::Zero();  // base x, y, phi at t = 0
  Eigen::VectorXd arm_start;                        // arm joints at t = 0 (dof - 3)
  Eigen::Vector3d goal = Eigen::Vector3d::Zero();   // base x, y, phi at T (phi: any whole turn from it reaches it)
  double goal_tol_pos = 0.5, goal_tol_yaw = 0.7853981633974483;
  core::Transform grasp_pose;                               // tool pose at T2 (world)
  Eigen::Vector3d approach_dir = Eigen::Vector3d::UnitX();  // n_g, unit, world
  Eigen::Vector2d part_xy = Eigen::Vector2d::Zero();        // grasping-area centre
  double grasp_area_rmin = 0.35, grasp_area_rmax = 0.8;     // base distance to the part during grasping
  RhoPoly rho;
  double gamma = 0.96;    // success-probability threshold
  double stroke = 0.085;  // finger travel: T2 - T1 = stroke / S_c
  bool vary_sc = true;    // false: S_c fixed at sc_fixed
  double sc_fixed = 0.15;
  double base_speed_limit = 2.0, base_yaw_rate_limit = 3.141592653589793;
  Eigen::VectorXd arm_rate_limits;  // (dof - 3), rad/s
  std::vector<SphereObstacle> obstacles;
  std::vector<BodySphere> body_spheres;
  int tool_link = -1;                             // link index of the gripper tool frame
  void validate(const core::Robot& robot) const;  // throws std::invalid_argument
};

struct PickupSettings {
  int samples_per_interval = 8;  // m instants in each of [0,T1], [T1,T2], [T2,T]
  std::vector<int> degrees;      // per DOF; empty: default_degrees() (5 base, 5 arm joints 1-3, 3 wrists)
  // Non-holonomic base, in normalised time: |x_s sin phi - y_s cos phi| <= tol * L with L the
  // start-part-goal distance, i.e. lateral speed <= tol L / T (heading error ~ tol rad at mean speed).
  double nonholonomic_tol = 0.002;
  HessianMode hessian = HessianMode::exact;              // exact (eval_hessian) | limited_memory (Ipopt's L-BFGS)
  CoefficientBasis basis = CoefficientBasis::bernstein;  // Ipopt's coefficient variables (results: monomial)
  MuStrategy mu_strategy = MuStrategy::monotone;         // Ipopt barrier update
  double mu_init = 1e-2;
  double velocity_tol = 0.005;         // |J q' - S_g n_g| per component (m/s) during grasping
  double angular_velocity_tol = 0.01;  // |omega| per component (rad/s) during grasping
  double collision_margin = 0.02;      // m
  double joint_limit_margin = 0.05;    // rad, sampled position limits tightened (limits hold between samples)
  double t_min = 0.5, t_max = 100.0;   // bounds on T (s)
  // Yaw and arm joint rate limits: hull bounds each rate polynomial by its Bernstein points of
  // degree rate_hull_degree (the convex-hull property: the limit then holds on all of [0, T], with
  // a small margin of conservatism, in a few rows per DOF); sampled: at the m samples per interval.
  RateRows rate_rows = RateRows::hull;
  int rate_hull_degree = 12;
  double tol = 1e-6, constr_viol_tol = 1e-6;
  int max_iter = 400;
  double max_cpu_time = 20.0;  // per stage (s)
  int print_level = 0;
  bool derivative_test = false;                                    // runs Ipopt's first-order derivative checker
  std::vector<std::pair<std::string, std::string>> ipopt_options;  // extra Ipopt options (name, value)
  std::string output_file;  // non-empty: Ipopt's log (print level 5) goes to this file
  // Active set: joint-position and collision rows only where the trajectory comes within these
  // windows of them; every row is checked after each solve and violated/near rows join for a
  // re-solve from the last solution (at most active_max_rounds runs). false: every row always.
  bool active_set = true;
  double active_joint_window = 0.3;       // rad
  double active_collision_window = 0.15;  // m
  int active_max_rounds = 6;
  double mu_resolve = 1e-4;       // mu_init of the re-solves (warm: multipliers carried over)
  double warm_start_push = 1e-6;  // Ipopt's warm_start_{bound,slack_bound,mult_bound}_push
  bool timing_seed = true;        // stage 3 starts from grasp_timing_seed()
  double timing_fraction = 0.5;   // ... with this fraction of the full slow-down (in log T)
  // The successive refinement also solves the all-constraint NLP (stage 0) once from the stage-1
  // solution (a direct track that is not committed to the stage-2 IK branch and grasp timing) and
  // returns the better of the two (PickupResult::direct; false: the five stages only).
  bool direct_track = true;
  int direct_max_iter = 200;  // its Ipopt iterations (a hedge: it must not dominate the time)
  // Stages 2-5 run from up to this many arm configurations at T2 (1: the single IK seed of the
  // paper's scheme), in this order: the IK solution (grasp_ik_seed); the same with the arm joint
  // whose limit rows carry the largest multipliers in that run (the limit that costs the most
  // time) turned by 2 pi away from that limit; the other IK branches (grasp_arm_seeds: shoulder,
  // elbow, wrist flips, then their combinations); further turns. The shortest
  // solution is kept. A later seed's run (and the direct track) stops after any Ipopt run whose T
  // is not below the best found so far: rows only join, its T would not fall below it again.
  int arm_seeds = 2;
  // (Iteration caps on the successive refinement, its re-solves and stages 4-5 were measured and
  // dropped: the slowest solves are the hard ones, and every cap lost problems; bench/PICKUP.md.)
  bool warm_start_stages = true;  // stages 4 and 5 start from the previous stage's multipliers
  // Wall-clock budget of one solve_successive / solve_single_shot call (s; 0: none). Each Ipopt run
  // stops before an iteration that would end past the deadline (its intermediate callback, the
  // next iteration taken as long as the last), no stage, arm seed or direct track starts after a
  // run was stopped so, and the result keeps the best feasible solution found before (status time_limit).
  // Wall time, not CPU: it is what a caller waits for (on a loaded machine the two differ).
  double time_limit = 0.0;
  // The trajectory between the regular samples is checked at this many subdivisions of each gap;
  // where a body comes closer than collision_margin / 2 (stages with collision rows) or an arm joint
  // closer than joint_limit_margin / 2 to its limit, a row at that instant joins and the stage is
  // re-solved (0: samples only, as the paper).
  int dense_subdivisions = 16;
  // ... and where the base's lateral speed exceeds this (m/s; > 0), a non-holonomic row at that
  // instant joins (0: not checked between the samples). Off by default: at 0.02 m/s (the mean
  // Python's dense check accepts) it cost CPU and lost problems on the paper's and the side
  // layouts, and traded shorter T for solved problems on the behind layout (bench/PICKUP.md, issue 37).
  double dense_nonholonomic = 0.0;
  double seed_speed = 1.0;       // heuristic seed: T = path length / seed_speed
  unsigned seed = 0;             // random seeds (arm perturbation, single-shot baseline)
  double arm_seed_noise = 0.05;  // rad, heuristic seed arm perturbation
};

// A subset of a stage's optional rows (joint-position and collision rows), for the active-set
// solve: a joint or collision row at a regular sample or at any instant s = w0 s1 + w1 s2 + w2
// (e.g. between samples, where the dense check found the trajectory too close to a limit); and
// non-holonomic rows at instants between the samples (every regular sample has one anyway).
struct PickupRowSubset {
  struct Joint {
    int sample = 0;  // >= 0: a regular sample (w unused); -1: the instant given by w
    int joint = 0;   // arm joint 0..dof-4
    double w[3] = {0.0, 0.0, 0.0};
  };
  struct Collision {
    int sample = -1;  // >= 0: a regular sample (w unused); -1: the instant given by w
    double w[3] = {0.0, 0.0, 0.0};
    int pair = 0;  // body_sphere * num_obstacles + obstacle
  };
  struct Instant {
    double w[3] = {0.0, 0.0, 0.0};
  };
  std::vector<Joint> joints;
  std::vector<Collision> collisions;
  std::vector<Instant> nonholonomic;
  void merge(const PickupRowSubset& other);  // union, without duplicates
  int size() const { return static_cast<int>(joints.size() + collisions.size() + nonholonomic.size()); }
};

// The constraint system of one stage, evaluated natively (exposed for tests and the checker).
// Regular samples: m per interval, in time order ([0, T1): j/m; [T1, T2]: j/(m-1); (T2, T]: j/m).
class PickupConstraints {
 public:
  // subset == nullptr: every joint-position and collision row at every regular sample (the full
  // stage); otherwise exactly the optional rows of the subset (all other rows always).
  PickupConstraints(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings, int stage,
                    const PickupRowSubset* subset = nullptr);
  int num_vars() const { return n_; }
  int num_constraints() const { return static_cast<int>(rows_.size()); }
  int num_nonzeros() const { return static_cast<int>(jac_col_.size()); }
  int stage() const { return stage_; }
  const PolyTraj& traj() const { return traj_; }
  int idx_s1() const { return nc_; }      // T1 / T
  int idx_s2() const { return nc_ + 1; }  // T2 / T
  int idx_T() const { return nc_ + 2; }
  int idx_Sg() const { return nc_ + 3; }
  int idx_Sc() const { return nc_ + 4; }
  // Upper bound on S_g implied by rho >= gamma (RhoPoly::sg_upper_bound; NaN: gamma unattainable).
  double sg_cap() const { return sg_cap_; }
  void bounds(Eigen::VectorXd& x_lo, Eigen::VectorXd& x_hi, Eigen::VectorXd& g_lo, Eigen::VectorXd& g_hi) const;
  void eval_g(const double* x, double* g) const;
  void jac_structure(int* rows, int* cols) const;
  void eval_jac(const double* x, double* values) const;
  Eigen::MatrixXd dense_jacobian(const Eigen::VectorXd& x) const;
  // Hessian of the Lagrangian sum_r lambda_r g_r(x) (the objective T is linear): the lower
  // triangle of all variables, row-major (row i >= col j); exact for the polynomial rows, forward
  // differences of the exact gradients in q for the forward-kinematics rows.
  int num_hess_nonzeros() const { return n_ * (n_ + 1) / 2; }
  void hess_structure(int* rows, int* cols) const;
  void eval_hessian(const double* x, const double* lambda, double* values) const;
  Eigen::MatrixXd dense_hessian(const Eigen::VectorXd& x, const Eigen::VectorXd& lambda) const;  // symmetric
  // Largest violation of the constraint bounds and the variable bounds at x.
  double max_violation(const Eigen::VectorXd& x) const;
  std::vector<std::string> row_names() const;  // "kind@sample" for diagnostics
  // A key of row r that is the same in every stage and row subset: (kind, instant w0, w1, w2, aux)
  // (w = -1 for the rows of the time variables).
  std::array<double, 5> row_key(int r) const;
  int num_regular_samples() const { return nreg_; }
  // Collision rows of a stage: from stage 5 on (and in stage 0) every body sphere; before, the
  // spheres moved by the base DOFs only (the base's path constraints, C_mbpath of stage 1).
  bool pair_in_stage(int pair) const;  // pair = body_sphere * num_obstacles + obstacle
  bool has_collision_rows() const;
  // The optional rows at the regular samples whose slack at x is below the window (violated ones
  // included): joint rows within joint_window (rad) of the tightened limits, collision rows whose
  // clearance is within collision_window (m) of the collision margin (pairs of pair_in_stage).
  PickupRowSubset near_rows(const Eigen::VectorXd& x, double joint_window, double collision_window) const;
  // Dense check between the regular samples (each gap split into `subdivisions`): per gap and
  // body/obstacle pair, the instant of least clearance when that clearance is below `threshold`;
  // per gap and arm joint, the instant of largest excursion when the joint comes closer than
  // joint_limit_margin - joint_slack to its limit; per gap, the instant of largest lateral base
  // speed when it exceeds settings.dense_nonholonomic (a long T leaves seconds between samples,
  // where a polynomial base path may slide sideways). min_clearance (optional) receives the least
  // clearance over the dense instants and the samples.
  PickupRowSubset dense_points(const Eigen::VectorXd& x, int subdivisions, double threshold, double joint_slack,
                               double* min_clearance = nullptr) const;

 private:
  struct Sample {
    double w[3];
  };  // s = w0 s1 + w1 s2 + w2
  struct Row {
    int kind, sample, aux;
    unsigned dof_mask;
    bool sg, sc;
    double lo, hi;
    int jac_begin;
  };
  void add_row(int kind, int sample, int aux, unsigned dof_mask, bool sg, bool sc, double lo, double hi);
  // The constructor's phases (cpp/src/pickup/nlp_layout.cpp): the rate rows' Bernstein hull, the
  // regular samples, which optional rows a subset keeps (extra samples appended), the rows.
  struct RowSelection;
  void build_rate_hull();
  void place_samples(int per_interval);
  RowSelection select_rows(const PickupRowSubset* subset);
  void add_sample_rows(const RowSelection& sel, double nh_bound);
  void add_joint_row(int sample, int joint);
  void add_collision_rows(int sample, const std::vector<int>& pairs);
  struct Kin;  // kinematic state at one sample (cpp/src/pickup/nlp_detail.hpp)
  void sample_rows(const double* x, int sample, int r0, int r1, double* g, double* jac) const;
  void kinematics(Kin& k, const double* x, int sample, int r0, int r1) const;
  void update_kinematics(Kin& k) const;  // FK and tool Jacobians at k.q, k.qd
  static bool is_kinematic(int kind);
  // Value of row R and its partials in (q, q') (the non-holonomic row: in (q, T q')) and S_g.
  double row_partials(const Row& R, Kin& k, Eigen::VectorXd& cq, Eigen::VectorXd& cqd, double& dsg) const;
  void sample_hessian(const double* x, const double* lambda, int sample, Eigen::MatrixXd& H) const;
  // sample_hessian's phases (cpp/src/pickup/hessian.cpp): the weighted rows' gradient and Hessian in
  // z = (q, q'), then chained through y = (q, P_s, T) into the variables.
  struct ZHessian;
  bool z_polynomial_terms(const double* lambda, int r0, int r1, const Kin& k, ZHessian& z) const;
  void z_kinematic_terms(const double* lambda, int r0, int r1, Kin& k, ZHessian& z) const;
  void chain_to_variables(const double* x, int sample, const Kin& k, const ZHessian& z, Eigen::MatrixXd& H) const;

  const core::Robot& robot_;
  const PickupProblem& pb_;
  PickupSettings st_;
  int stage_;
  PolyTraj traj_;
  int nc_ = 0, n_ = 0, dof_ = 0, level_ = 0, nreg_ = 0;
  double sg_cap_ = 0.0;
  std::vector<unsigned> body_mask_;         // DOFs moving each body sphere
  std::vector<Eigen::MatrixXd> rate_hull_;  // per DOF: monomial coefficients -> Bernstein points of P_s
  std::vector<Sample> samples_;
  std::vector<Row> rows_;
  std::vector<int> sample_row_begin_;  // rows of sample s: [begin[s], begin[s+1]); special rows after
  std::vector<int> jac_row_, jac_col_;
};

struct StageResult {
  int stage = 0;
  SolveStatus status = SolveStatus::not_run;
  std::string ipopt_status;  // Ipopt's ApplicationReturnStatus / SolverReturn as text
  bool success = false;
  double seconds = 0.0;        // wall time of the stage (Ipopt runs, checks, and in solve_successive its seed)
  double cpu_seconds = 0.0;    // its thread CPU time (the machine may be shared)
  int iterations = 0;          // over all active-set rounds
  int rounds = 0;              // Ipopt runs (active-set re-solves + 1)
  int rows = 0;                // constraint rows of the last run
  double objective = 0.0;      // T
  double max_violation = 0.0;  // at the returned x
  Eigen::VectorXd x;
};

struct PickupResult {
  SolveStatus status = SolveStatus::not_run;  // of the last attempted stage (solved when all succeeded)
  bool success = false;
  int stages_completed = 0;  // the returned x is the solution of this stage (0: the seed)
  std::vector<StageResult> stages;
  Eigen::VectorXd x;  // last good solution
  double total_seconds = 0.0;
  double total_cpu_seconds = 0.0;
  double T = 0, T1 = 0, T2 = 0, S_g = 0, S_c = 0;
  PolyTraj traj;  // in absolute time: time_scale = T, coefficients x[0 : num_coeffs]
  // solve_successive with settings.direct_track: the all-constraint solve from the stage-1
  // solution (stage 0 = not run), and whether its solution is the one returned (x, T, ...;
  // then stages_completed is 5 too, the stage records stay those of the five stages).
  StageResult direct;
  bool direct_chosen = false;
  // The arm seeds of stages 2-5 (PickupSettings::arm_seeds): how many were tried, which one the
  // stage records (and, unless the direct track won, x) come from, the final T of each (NaN:
  // failed or stopped by the bound), and the time of the runs not kept (in the totals).
  int arm_seeds_tried = 0;
  int arm_seed_chosen = 0;
  std::vector<double> arm_seed_T;
  double search_seconds = 0.0, search_cpu_seconds = 0.0;
};

// The heuristic seed of stage 1: base through a grasping-area point, arm at arm_start (+ noise).
Eigen::VectorXd heuristic_seed(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings);
// Stage-2 warm start: the arm polynomials re-fitted to blend from arm_start to a (multi-start,
// damped least-squares) IK solution of the grasp pose at the base pose of x at T2; base unchanged.
Eigen::VectorXd grasp_ik_seed(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                              const Eigen::VectorXd& x);
// The arm configurations at T2 of the stage-2 seeds: `path` is x with its base path (bent through
// a reachable base pose if needed), arms[0] the configuration of grasp_ik_seed; with flips (6-joint
// UR-type arm) also the same grasp on the other IK branches DLS reaches within the joint limits:
// shoulder, elbow, wrist flipped, then shoulder+elbow, shoulder+wrist, elbow+wrist, all three.
struct GraspArmSeeds {
  Eigen::VectorXd path;
  std::vector<Eigen::VectorXd> arms;  // full configurations q(T2), dof entries
};
GraspArmSeeds grasp_arm_seeds(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                              const Eigen::VectorXd& x, bool flips);
// The stage-2 seed: `path` with the arm polynomials blended from arm_start to q2 at s2 (then held).
Eigen::VectorXd arm_blend_seed(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                               const Eigen::VectorXd& path, const Eigen::VectorXd& q2);
// q2 with one arm joint turned by 2 pi away from a joint limit that `solution` (a trajectory from
// the seed of q2) runs into, one configuration per such joint and side, where the turned value is
// within the limits: the same grasp pose, but the joint's polynomial has room on that side.
// Ordered by price (per DOF, e.g. the multipliers of its limit rows; empty: joint order), highest first.
std::vector<Eigen::VectorXd> wound_arm_configurations(const core::Robot& robot, const PickupProblem& problem,
                                                      const PickupSettings& settings, const Eigen::VectorXd& q2,
                                                      const Eigen::VectorXd& solution,
                                                      const Eigen::VectorXd& price = Eigen::VectorXd());
// Stage-3 warm start: the same path in normalised time, slowed down: T moves `fraction` of the way
// (in log T; 0.5: the geometric mean) from its value to the T at which the tool's rms speed over the grasping samples
// is S_g; T1 moves to keep (T2 - T1) S_c = stroke. x unchanged when that would not slow it down.
Eigen::VectorXd grasp_timing_seed(const core::Robot& robot, const PickupProblem& problem,
                                  const PickupSettings& settings, const Eigen::VectorXd& x, double fraction = 0.5);
// A random seed for the single-shot baseline: a_x0 = x_i, a_y0 = y_i, a_phi0 = phi_i, others
// random, 0 <= T1 < T2 <= T (seeded by settings.seed).
Eigen::VectorXd random_seed(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings);
// One Ipopt solve of a stage (1..5) from x0; stage 0 = all constraints (single shot). Never throws
// for solver failures: they are statuses. Throws std::invalid_argument for bad input.
StageResult solve_stage(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                        int stage, const Eigen::VectorXd& x0);
// The five stages of Sec. V-B from the heuristic seed (or x0 when given, non-empty).
PickupResult solve_successive(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                              const Eigen::VectorXd& x0 = Eigen::VectorXd());
// The baseline "without sequencing": all constraints at once from random_seed().
// All constraints at once (stage 0) from the random seed (random_seed, settings.seed), or from x0
// when it is given (non-empty; e.g. a stage-1 solution: the direct track on its own).
PickupResult solve_single_shot(const core::Robot& robot, const PickupProblem& problem, const PickupSettings& settings,
                               const Eigen::VectorXd& x0 = Eigen::VectorXd());
// Default polynomial degrees for a robot with `dof` DOFs (3 base + arm).
std::vector<int> default_degrees(int dof);
// The degrees a solve uses: settings.degrees, or default_degrees(dof) when empty.
std::vector<int> resolved_degrees(const PickupSettings& settings, int dof);

}  // namespace pickplan::pickup
