// Seeds of the pick-up NLP: the heuristic stage-1 seed, the IK warm start of the arm for stage 2,
// and the random seeds of the single-shot baseline.
#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Dense>

#include "pickplan/core/ik.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {
namespace {
// The S_g bound of PickupConstraints (sg_hi when rho >= gamma is unattainable: seeds still work).
double sg_cap(const PickupProblem& pb) {
  const double a = pb.vary_sc ? pb.rho.sc_lo : pb.sc_fixed, b = pb.vary_sc ? pb.rho.sc_hi : pb.sc_fixed;
  const double cap = pb.rho.sg_upper_bound(pb.gamma, a, b);
  return std::isnan(cap) ? pb.rho.sg_hi : cap;
}
}  // namespace

namespace {
// The base's seed path: a cubic in s = t / T per coordinate, (cx, cy), and the fraction s_m where
// it passes the grasping area; vmax its peak speed in s.
struct BaseCubic {
  Eigen::Vector4d cx, cy;
  double sm = 0.5, vmax = 1.0;
};

// A cubic leaving the start along its heading, through a grasping-area point bp at s_m, to the
// goal. A small deterministic search over (bp direction about u0, start speed, s_m) picks the
// curve whose end heading is within the goal tolerance and whose peak/mean speed ratio is smallest.
BaseCubic search_base_cubic(const PickupProblem& pb, const Eigen::Vector2d& u0) {
  const Eigen::Vector2d s0 = pb.start.head<2>(), g0 = pb.goal.head<2>();
  const double rmid = 0.5 * (pb.grasp_area_rmin + pb.grasp_area_rmax);
  double best = 1e300;
  BaseCubic c;
  for (int ia = -9; ia <= 9; ++ia)
    for (double f : {0.5, 0.75, 1.0, 1.5})
      for (double smc : {0.3, 0.4, 0.5, 0.6}) {
        const double ang = ia * M_PI / 18;
        const Eigen::Vector2d b = pb.part_xy + rmid * Eigen::Vector2d(std::cos(ang) * u0.x() - std::sin(ang) * u0.y(),
                                                                      std::sin(ang) * u0.x() + std::cos(ang) * u0.y());
        Eigen::Matrix<double, 4, 4> A;
        A << 1, 0, 0, 0, 0, 1, 0, 0, 1, smc, smc * smc, smc * smc * smc, 1, 1, 1, 1;
        const double v0 = f * ((b - s0).norm() + (g0 - b).norm());
        const Eigen::Vector4d ax = A.lu().solve(Eigen::Vector4d(s0.x(), v0 * std::cos(pb.start[2]), b.x(), g0.x()));
        const Eigen::Vector4d ay = A.lu().solve(Eigen::Vector4d(s0.y(), v0 * std::sin(pb.start[2]), b.y(), g0.y()));
        double vmax = 0.0, vsum = 0.0;
        for (int k = 0; k <= 50; ++k) {
          const double s = k / 50.0;
          const double dx = ax[1] + s * (2 * ax[2] + 3 * s * ax[3]), dy = ay[1] + s * (2 * ay[2] + 3 * s * ay[3]);
          vmax = std::max(vmax, std::hypot(dx, dy));
          vsum += std::hypot(dx, dy) / 51;
        }
        const double he = std::atan2(ay[1] + 2 * ay[2] + 3 * ay[3], ax[1] + 2 * ax[2] + 3 * ax[3]);
        const double dh = std::remainder(he - pb.goal[2], 2 * M_PI);
        const double score = 100.0 * std::max(0.0, std::abs(dh) - 0.9 * pb.goal_tol_yaw) + vmax / std::max(vsum, 1e-9);
        if (score < best) {
          best = score;
          c.sm = smc;
          c.cx = ax;
          c.cy = ay;
          c.vmax = vmax;
        }
      }
  return c;
}

// Fits the base's coefficients in x (x, y and the heading unwrapped along the path) to the cubic,
// the start weighted up.
void fit_base_path(const PolyTraj& tr, const PickupProblem& pb, const BaseCubic& c, double* x) {
  const Eigen::Vector4d &cx = c.cx, &cy = c.cy;
  const int K = 60;
  Eigen::VectorXd ts(K), xs(K), ys(K), ps(K), ws = Eigen::VectorXd::Ones(K);
  double prev = pb.start[2];
  for (int k = 0; k < K; ++k) {
    const double s = double(k) / (K - 1);
    ts[k] = s;
    xs[k] = cx[0] + s * (cx[1] + s * (cx[2] + s * cx[3]));
    ys[k] = cy[0] + s * (cy[1] + s * (cy[2] + s * cy[3]));
    const double dx = cx[1] + s * (2 * cx[2] + 3 * s * cx[3]), dy = cy[1] + s * (2 * cy[2] + 3 * s * cy[3]);
    double h = std::atan2(dy, dx);
    while (h - prev > M_PI) h -= 2 * M_PI;
    while (h - prev < -M_PI) h += 2 * M_PI;
    ps[k] = prev = h;
  }
  ws[0] = 100.0;
  tr.fit_dof(0, ts, xs, x, ws);
  tr.fit_dof(1, ts, ys, x, ws);
  tr.fit_dof(2, ts, ps, x, ws);
}
}  // namespace

Eigen::VectorXd heuristic_seed(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st) {
  pb.validate(robot);
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int nc = tr.num_coeffs();
  Eigen::VectorXd x = Eigen::VectorXd::Zero(nc + 5);
  const Eigen::Vector2d s0 = pb.start.head<2>(), g0 = pb.goal.head<2>();
  Eigen::Vector2d u0 = 0.5 * (s0 + g0) - pb.part_xy;
  if (u0.norm() < 1e-9) u0 = Eigen::Vector2d::UnitX();
  u0.normalize();
  // Base: a cubic through the grasping area (search_base_cubic); T then puts its peak speed at 90 %
  // of the limit.
  const BaseCubic c = search_base_cubic(pb, u0);
  const double T = std::max(1.0, c.vmax / (0.9 * pb.base_speed_limit));
  const double sc = pb.vary_sc ? pb.rho.sc_hi : pb.sc_fixed, dtg = pb.stroke / sc;
  const double tm = c.sm * T;
  const double T1 = std::max(0.0, tm - 0.5 * dtg), T2 = T1 + dtg;
  fit_base_path(tr, pb, c, x.data());
  std::mt19937 rng(st.seed);
  std::normal_distribution<double> noise(0.0, st.arm_seed_noise);
  for (int i = 3; i < robot.dof(); ++i) {
    x[tr.offset(i)] = pb.arm_start[i - 3];
    if (tr.degree(i) >= 1) x[tr.offset(i) + 1] = noise(rng);  // small random drift, start held exactly
  }
  x[nc] = T1 / T;
  x[nc + 1] = T2 / T;
  x[nc + 2] = T;
  x[nc + 3] = 0.5 * (pb.rho.sg_lo + sg_cap(pb));
  x[nc + 4] = sc;
  return x;
}

Eigen::VectorXd random_seed(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st) {
  pb.validate(robot);
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int nc = tr.num_coeffs();
  std::mt19937 rng(st.seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0), ut(0.0, 1.0);
  Eigen::VectorXd x(nc + 5);
  for (int k = 0; k < nc; ++k) x[k] = u(rng);
  for (int i = 0; i < 3; ++i) x[tr.offset(i)] = pb.start[i];
  const double T = 5.0 + 25.0 * ut(rng);
  double a = ut(rng), b = ut(rng);
  if (a > b) std::swap(a, b);
  if (b - a < 0.01) b = std::min(1.0, a + 0.01);
  x[nc] = a;
  x[nc + 1] = b;
  x[nc + 2] = T;
  x[nc + 3] = pb.rho.sg_lo + ut(rng) * (sg_cap(pb) - pb.rho.sg_lo);
  x[nc + 4] = pb.vary_sc ? pb.rho.sc_lo + ut(rng) * (pb.rho.sc_hi - pb.rho.sc_lo) : pb.sc_fixed;
  return x;
}

namespace {

// The seeds' IK (core/ik.hpp): plain damped least squares, every step kept, solved to machine
// precision; the base path's heading is never moved by IK (it follows the path's tangent).
constexpr int kSeedIkIterations = 150;
constexpr double kSeedIkTolerance = 1e-10;  // m and rad: descents stop here
constexpr double kSeedIkDamping = 1e-4;
constexpr double kSeedIkMaxStep = 0.3;     // Euclidean norm of one step (rad and m)
constexpr double kReachTolerance = 1e-6;   // a residual below this reaches the grasp pose
constexpr double kBaseWeight = 0.3;        // whole-body IK: weight of the base translation
constexpr double kAreaInset = 0.02;        // m: the whole-body IK's base kept this far inside the grasping area
constexpr double kUnreachedPenalty = 1e3;  // arm seeds: score per unit residual of a seed that misses the pose

// The arm alone (base_weight 0) or the arm and the base translation (base_weight > 0).
core::DlsSettings seed_ik_settings(const core::Robot& robot, const PickupSettings& st, double base_weight) {
  core::DlsSettings s;
  s.rotation_error = core::IkRotationError::sine_axis;
  s.max_iterations = kSeedIkIterations;
  s.position_tolerance = s.rotation_tolerance = kSeedIkTolerance;
  s.damping_schedule = core::IkDamping::fixed;
  s.damping = kSeedIkDamping;
  s.max_stalled_iterations = 0;
  s.max_step = kSeedIkMaxStep;
  s.step_norm = core::IkStepNorm::euclidean;
  s.limit_margin = st.joint_limit_margin;
  s.weights.assign(robot.dof(), 1.0);
  s.weights[0] = s.weights[1] = base_weight;
  s.weights[2] = 0.0;
  return s;
}

// The error's norm as the steps see it: position and sin(angle) * axis.
double residual(const core::IkSolution& sol) { return std::hypot(sol.position_error, std::sin(sol.rotation_error)); }

// IK of the tool for the grasp pose from q (updated in place); returns the residual before the
// last step. A descent that does not converge oscillates, and the arm seeds choose among such
// starts by this residual (their choice was tuned with it: the final one loses case 1's flip).
double grasp_ik(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, Eigen::VectorXd& q,
                double base_weight = 0.0) {
  core::DlsSettings s = seed_ik_settings(robot, st, base_weight);
  s.max_iterations = kSeedIkIterations - 1;
  const core::IkSolution before_last = core::solve_ik(robot, pb.tool_link, core::Transform{}, pb.grasp_pose, q, s);
  s.max_iterations = 1;  // the last step (none when converged)
  q = core::solve_ik(robot, pb.tool_link, core::Transform{}, pb.grasp_pose, before_last.q, s).q;
  return residual(before_last);
}

// Whole-body IK (base translation weighted by kBaseWeight) from q, for the grasp pose; the base is
// then kept in the grasping area and the arm re-solved. Returns the residual.
double body_ik(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, Eigen::VectorXd& q) {
  grasp_ik(robot, pb, st, q, kBaseWeight);
  Eigen::Vector2d d = q.head<2>() - pb.part_xy;
  const double r = std::clamp(d.norm(), pb.grasp_area_rmin + kAreaInset, pb.grasp_area_rmax - kAreaInset);
  if (d.norm() > 1e-9) q.head<2>() = pb.part_xy + r * d.normalized();
  return grasp_ik(robot, pb, st, q);
}

}  // namespace

namespace {
// Bends the base path x (into out) so that it passes q's base position at s2: the old path plus the
// displacement at s2 faded out smoothly away from s2; the heading then follows the new path's
// tangent, forwards or backwards as the old path drove (keeps the non-holonomic rows nearly met).
// Then the arm again, at the base pose the new path actually has at s2 (q updated).
void bend_base_path(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, const PolyTraj& tr,
                    const Eigen::VectorXd& x, double s2, const Eigen::VectorXd& q2, Eigen::VectorXd& q,
                    Eigen::VectorXd& out) {
  const int n = robot.dof();
  const Eigen::Vector2d delta = q.head<2>() - q2.head<2>();
  const int K = 60;
  Eigen::VectorXd ss(K), vx(K), vy(K), vp(K), w = Eigen::VectorXd::Ones(K);
  Eigen::VectorXd qk(n), qdk(n);
  w[0] = 100.0;
  for (int k = 0; k < K; ++k) {
    ss[k] = double(k) / (K - 1);
    tr.eval(x.data(), ss[k], qk.data(), nullptr, nullptr);
    const double b = std::exp(-std::pow((ss[k] - s2) / 0.25, 2)) * (k == 0 ? 0.0 : 1.0);
    vx[k] = qk[0] + b * delta.x();
    vy[k] = qk[1] + b * delta.y();
    vp[k] = qk[2];  // the old heading, turned below
  }
  tr.fit_dof(0, ss, vx, out.data(), w);
  tr.fit_dof(1, ss, vy, out.data(), w);
  // The heading: the old path's, turned to the nearer direction of the new path's tangent, so a leg
  // driven backwards keeps its heading. The tangent alone turned such a leg round by pi (and each
  // cusp with it), and stage 2 then started far off the non-holonomic rows: behind the start, 400
  // Ipopt iterations without converging where it now takes 20-50 (bench/PICKUP.md, session 35).
  for (int k = 1; k < K; ++k) {
    tr.eval(out.data(), ss[k], qk.data(), qdk.data(), nullptr);
    if (qdk.head<2>().norm() > 1e-9) vp[k] += std::remainder(std::atan2(qdk[1], qdk[0]) - vp[k], M_PI);
  }
  tr.fit_dof(2, ss, vp, out.data(), w);
  for (int j = 0; j < 3; ++j) out[tr.offset(j)] = pb.start[j];
  // The arm again, at the base pose the new path actually has at s2.
  tr.eval(out.data(), s2, qk.data(), nullptr, nullptr);
  q.head<3>() = qk.head<3>();
  grasp_ik(robot, pb, st, q);
}

// The arm configuration `best` (arm joints from index 3, a 6-joint UR-type arm) on another IK
// branch, by closed-form approximation (mask bit 0 the shoulder flip, 1 the elbow, 2 the wrist),
// its revolute joints wrapped to the turn nearest the arm's start.
Eigen::VectorXd flipped_arm(const Eigen::VectorXd& best, int mask, const PickupProblem& pb) {
  Eigen::VectorXd f = best;
  double* a = f.data() + 3;
  if (mask & 1) {
    a[0] += M_PI;
    a[1] = -M_PI - a[1];
    a[2] = -a[2];
    a[3] = -M_PI - a[3];
    a[4] = -a[4];
  }
  if (mask & 2) {
    a[1] += a[2];
    a[3] += a[2];
    a[2] = -a[2];
  }
  if (mask & 4) {
    a[3] += M_PI;
    a[4] = -a[4];
    a[5] += M_PI;
  }
  for (int j : {0, 1, 3, 5}) a[j] = pb.arm_start[j] + std::remainder(a[j] - pb.arm_start[j], 2 * M_PI);
  return f;
}
}  // namespace

GraspArmSeeds grasp_arm_seeds(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                              const Eigen::VectorXd& x, bool flips) {
  pb.validate(robot);
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int nc = tr.num_coeffs(), n = robot.dof();
  if (x.size() != nc + 5)
    throw std::invalid_argument("grasp_arm_seeds: expected " + std::to_string(nc + 5) + " variables");
  const double s2 = x[nc + 1];
  Eigen::VectorXd q2(n);
  tr.eval(x.data(), s2, q2.data(), nullptr, nullptr);
  // Deterministic multi-start: the start configuration with the pan and wrist turned.
  Eigen::VectorXd best;
  double best_score = 1e300;
  for (double pan : {0.0, M_PI / 2, -M_PI / 2, M_PI})
    for (double w3 : {0.0, M_PI / 2, -M_PI / 2}) {
      Eigen::VectorXd q = q2;
      q.tail(n - 3) = pb.arm_start;
      q[3] += pan;
      q[n - 1] += w3;
      const double err = grasp_ik(robot, pb, st, q);
      const double score =
          (err > kReachTolerance ? kUnreachedPenalty * err : 0.0) + (q.tail(n - 3) - pb.arm_start).norm();
      if (score < best_score) {
        best_score = score;
        best = q;
      }
    }
  Eigen::VectorXd out = x;
  if (best_score >= kUnreachedPenalty * kReachTolerance) {
    // Out of reach from the stage-1 base pose at T2 (it tends to skim the grasping area's outer
    // edge): move the base too, then bend the base path through the new pose at s2.
    Eigen::VectorXd q = best;
    if (body_ik(robot, pb, st, q) < kReachTolerance) {
      bend_base_path(robot, pb, st, tr, x, s2, q2, q, out);
      best = q;
    }
  }
  // The same grasp on the arm's other IK branches (UR-type 6-joint arm: shoulder, elbow and wrist
  // flips and their combinations), each from its closed-form approximation refined by DLS: they
  // lead the stages to different local optima. The shoulder flip: pan + pi, the planar chain and
  // the wrist mirrored. The elbow flip: elbow -> -elbow, its angle moved to the shoulder lift and
  // wrist 1 (exact for equal upper arm and forearm; DLS corrects the rest). The wrist flip: wrist 1
  // and 3 + pi, wrist 2 mirrored.
  GraspArmSeeds g;
  g.path = out;
  g.arms = {best};
  const int na = n - 3;
  if (flips && na == 6) {
    const Eigen::VectorXd& lo = robot.lower_limits();
    const Eigen::VectorXd& hi = robot.upper_limits();
    for (int mask : {1, 2, 4, 3, 5, 6, 7}) {  // bit 0 shoulder, 1 elbow, 2 wrist: single flips first
      Eigen::VectorXd f = flipped_arm(best, mask, pb);
      if (grasp_ik(robot, pb, st, f) >= kReachTolerance) continue;
      bool inside = true, fresh = true;
      for (int j = 3; j < n; ++j)
        inside = inside && f[j] >= lo[j] + st.joint_limit_margin && f[j] <= hi[j] - st.joint_limit_margin;
      for (const auto& h : g.arms) fresh = fresh && (f - h).norm() > 1e-3;
      if (inside && fresh) g.arms.push_back(f);
    }
  }
  return g;
}

Eigen::VectorXd arm_blend_seed(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                               const Eigen::VectorXd& path, const Eigen::VectorXd& q2) {
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int nc = tr.num_coeffs(), n = robot.dof();
  if (path.size() != nc + 5 || q2.size() != n) throw std::invalid_argument("arm_blend_seed: wrong sizes");
  const double s2 = path[nc + 1];
  Eigen::VectorXd out = path;
  // Arm polynomials: smooth blend from arm_start to the IK solution at s2, then held.
  const int K = 40;
  Eigen::VectorXd ss(K), vals(K), w = Eigen::VectorXd::Ones(K);
  for (int j = 3; j < n; ++j) {
    for (int k = 0; k < K; ++k) {
      const double s = double(k) / (K - 1);
      const double u = std::min(1.0, s / std::max(s2, 1e-6)), b = u * u * (3 - 2 * u);
      ss[k] = s;
      vals[k] = pb.arm_start[j - 3] + b * (q2[j] - pb.arm_start[j - 3]);
    }
    ss[K - 1] = s2;  // the IK point itself, weighted
    vals[K - 1] = q2[j];
    w[K - 1] = 30.0;
    w[0] = 30.0;
    tr.fit_dof(j, ss, vals, out.data(), w);
  }
  return out;
}

std::vector<Eigen::VectorXd> wound_arm_configurations(const core::Robot& robot, const PickupProblem& pb,
                                                      const PickupSettings& st, const Eigen::VectorXd& q2,
                                                      const Eigen::VectorXd& solution, const Eigen::VectorXd& price) {
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int n = robot.dof();
  if (solution.size() != tr.num_coeffs() + 5 || q2.size() != n)
    throw std::invalid_argument("wound_arm_configurations: wrong sizes");
  // Where each arm joint of the solution comes within 1.5 margins of a limit (dense in s).
  Eigen::VectorXd lo = Eigen::VectorXd::Constant(n, 1e300), hi = -lo, q(n);
  for (int k = 0; k <= 200; ++k) {
    tr.eval(solution.data(), k / 200.0, q.data(), nullptr, nullptr);
    lo = lo.cwiseMin(q);
    hi = hi.cwiseMax(q);
  }
  std::vector<std::pair<double, Eigen::VectorXd>> found;
  const double m = st.joint_limit_margin;
  for (int j = 3; j < n; ++j) {
    const double L = robot.lower_limits()[j], U = robot.upper_limits()[j];
    for (int side : {-1, 1}) {
      const bool touches = side < 0 ? lo[j] <= L + 1.5 * m : hi[j] >= U - 1.5 * m;
      Eigen::VectorXd w = q2;
      w[j] -= side * 2 * M_PI;  // away from the limit it runs into
      if (touches && w[j] >= L + m && w[j] <= U - m) found.push_back({price.size() == n ? price[j] : 0.0, w});
    }
  }
  // The joint whose limits cost the most time first (stable: joint order among equals).
  std::stable_sort(found.begin(), found.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Eigen::VectorXd> out;
  for (auto& f : found) out.push_back(f.second);
  return out;
}

Eigen::VectorXd grasp_ik_seed(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                              const Eigen::VectorXd& x) {
  const GraspArmSeeds g = grasp_arm_seeds(robot, pb, st, x, false);
  return arm_blend_seed(robot, pb, st, g.path, g.arms.front());
}

Eigen::VectorXd grasp_timing_seed(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                                  const Eigen::VectorXd& x, double fraction) {
  pb.validate(robot);
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  PolyTraj tr(deg, 1.0);
  const int nc = tr.num_coeffs(), n = robot.dof();
  if (x.size() != nc + 5)
    throw std::invalid_argument("grasp_timing_seed: expected " + std::to_string(nc + 5) + " variables");
  const double s1 = x[nc], s2 = x[nc + 1], Sg = x[nc + 3], Sc = x[nc + 4];
  // Tool velocity per unit normalised time, v_j = J P_s, at the grasping samples; T such that the
  // tool's rms speed v / T during grasping is S_g (the speed stage 3 asks for).
  core::RobotWorkspace ws(robot);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, n);
  Eigen::VectorXd q(n), ps(n);
  double vv = 0.0;
  const int m = std::max(2, st.samples_per_interval);
  for (int j = 0; j < m; ++j) {
    const double s = s1 + (s2 - s1) * j / (m - 1);
    tr.eval(x.data(), s, q.data(), ps.data(), nullptr);
    robot.forward_kinematics(q.data(), ws);
    robot.point_jacobian(ws, pb.tool_link, Eigen::Vector3d::Zero(), J);
    const Eigen::Vector3d v = J.topRows<3>() * ps;
    vv += v.squaredNorm();
  }
  if (!(vv > 0.0)) return x;
  const double Tfull = std::clamp(std::sqrt(vv / m) / Sg, st.t_min, st.t_max);
  if (!(Tfull > x[nc + 2])) return x;  // only ever slows down
  // Halfway (geometrically) to the fully slowed T: stage 3 then approaches its T from both sides
  // (from the full slow-down it stopped at slower local optima in cases 3 and 6).
  const double T = x[nc + 2] * std::pow(Tfull / x[nc + 2], fraction);
  Eigen::VectorXd out = x;
  out[nc + 2] = T;
  out[nc] = std::max(0.0, s2 - pb.stroke / (T * Sc));  // (T2 - T1) S_c = stroke, T2 kept
  return out;
}

}  // namespace pickplan::pickup
