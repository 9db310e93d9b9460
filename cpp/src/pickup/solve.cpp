// Ipopt driver of the pick-up NLP: the TNLP adapter, seeds, the five stages of successive
// refinement (Sec. V-B) and the single-shot baseline. Ipopt + MUMPS is not thread-safe: one
// solve at a time per process.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <map>
#include <stdexcept>

#include <coin/IpIpoptApplication.hpp>
#include <coin/IpIpoptData.hpp>
#include <coin/IpTNLP.hpp>

#include "pickplan/pickup/nlp.hpp"
#include "nlp_detail.hpp"

namespace pickplan {
using namespace pickup_detail;

// ---- rho ---------------------------------------------------------------------------------------
namespace {
double binom(int n, int k) {
  double r = 1.0;
  for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
  return r;
}
// Bernstein basis values and derivatives (w.r.t. u) of degree n at u.
void bernstein(int n, double u, Eigen::VectorXd& b, Eigen::VectorXd& db) {
  b.resize(n + 1);
  db.resize(n + 1);
  for (int k = 0; k <= n; ++k) {
    b[k] = binom(n, k) * std::pow(u, k) * std::pow(1.0 - u, n - k);
    double d = 0.0;
    if (k > 0) d += k * std::pow(u, k - 1) * std::pow(1.0 - u, n - k);
    if (k < n) d -= (n - k) * std::pow(u, k) * std::pow(1.0 - u, n - k - 1);
    db[k] = binom(n, k) * d;
  }
}
// Second derivatives (w.r.t. u) of the Bernstein basis of degree n at u.
Eigen::VectorXd bernstein_dd(int n, double u) {
  Eigen::VectorXd d2(n + 1);
  auto mono = [&](int a, int b) { return std::pow(u, a) * std::pow(1.0 - u, b); };
  for (int k = 0; k <= n; ++k) {
    const int m = n - k;
    double d = 0.0;
    if (k >= 2) d += k * (k - 1) * mono(k - 2, m);
    if (k >= 1 && m >= 1) d -= 2.0 * k * m * mono(k - 1, m - 1);
    if (m >= 2) d += m * (m - 1) * mono(k, m - 2);
    d2[k] = binom(n, k) * d;
  }
  return d2;
}
}  // namespace

void RhoPoly::validate() const {
  if (coeffs.rows() < 1 || coeffs.cols() < 1) throw std::invalid_argument("rho: empty coefficient matrix");
  if (!coeffs.allFinite()) throw std::invalid_argument("rho: coefficients must be finite");
  if (!(sg_hi > sg_lo) || !(sc_hi > sc_lo))
    throw std::invalid_argument("rho: speed ranges must satisfy lo < hi, got S_g [" + std::to_string(sg_lo) + ", " +
                                std::to_string(sg_hi) + "], S_c [" + std::to_string(sc_lo) + ", " + std::to_string(sc_hi) + "]");
}

double RhoPoly::value(double sg, double sc) const {
  Eigen::VectorXd bu, dbu, bv, dbv;
  bernstein(static_cast<int>(coeffs.rows()) - 1, std::clamp((sg - sg_lo) / (sg_hi - sg_lo), 0.0, 1.0), bu, dbu);
  bernstein(static_cast<int>(coeffs.cols()) - 1, std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0), bv, dbv);
  return bu.dot(coeffs * bv);
}

Eigen::Vector2d RhoPoly::gradient(double sg, double sc) const {
  Eigen::VectorXd bu, dbu, bv, dbv;
  bernstein(static_cast<int>(coeffs.rows()) - 1, std::clamp((sg - sg_lo) / (sg_hi - sg_lo), 0.0, 1.0), bu, dbu);
  bernstein(static_cast<int>(coeffs.cols()) - 1, std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0), bv, dbv);
  return {dbu.dot(coeffs * bv) / (sg_hi - sg_lo), bu.dot(coeffs * dbv) / (sc_hi - sc_lo)};
}

Eigen::Matrix2d RhoPoly::hessian(double sg, double sc) const {
  Eigen::VectorXd bu, dbu, bv, dbv;
  const double u = std::clamp((sg - sg_lo) / (sg_hi - sg_lo), 0.0, 1.0), v = std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0);
  bernstein(static_cast<int>(coeffs.rows()) - 1, u, bu, dbu);
  bernstein(static_cast<int>(coeffs.cols()) - 1, v, bv, dbv);
  const Eigen::VectorXd ddu = bernstein_dd(static_cast<int>(coeffs.rows()) - 1, u);
  const Eigen::VectorXd ddv = bernstein_dd(static_cast<int>(coeffs.cols()) - 1, v);
  const double gu = sg_hi - sg_lo, gv = sc_hi - sc_lo;
  Eigen::Matrix2d h;
  h(0, 0) = ddu.dot(coeffs * bv) / (gu * gu);
  h(0, 1) = h(1, 0) = dbu.dot(coeffs * dbv) / (gu * gv);
  h(1, 1) = bu.dot(coeffs * ddv) / (gv * gv);
  return h;
}

double RhoPoly::sg_upper_bound(double gamma, double sc_a, double sc_b) const {
  constexpr int NG = 64, NC = 16;
  Eigen::MatrixXd bv(coeffs.cols(), NC);
  Eigen::VectorXd b, db;
  for (int j = 0; j < NC; ++j) {
    const double sc = sc_a + (sc_b - sc_a) * j / (NC - 1);
    bernstein(static_cast<int>(coeffs.cols()) - 1, std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0), b, db);
    bv.col(j) = b;
  }
  const Eigen::MatrixXd Cb = coeffs * bv;
  auto best = [&](double u) {  // max over the S_c grid of rho at S_g = sg_lo + u (sg_hi - sg_lo)
    bernstein(static_cast<int>(coeffs.rows()) - 1, u, b, db);
    return (b.transpose() * Cb).maxCoeff();
  };
  for (int i = NG - 1; i >= 0; --i) {
    if (best(double(i) / (NG - 1)) < gamma) continue;
    if (i == NG - 1) return sg_hi;
    // The crossing between grid points i (feasible) and i + 1 (not), by bisection.
    double a = double(i) / (NG - 1), c = double(i + 1) / (NG - 1);
    for (int k = 0; k < 40; ++k) (best(0.5 * (a + c)) >= gamma ? a : c) = 0.5 * (a + c);
    return sg_lo + (sg_hi - sg_lo) * c;
  }
  return std::numeric_limits<double>::quiet_NaN();
}

void PickupProblem::validate(const Robot& robot) const {
  const int na = robot.dof() - 3;
  if (na < 1) throw std::invalid_argument("robot: expected 3 base DOFs plus an arm, got " + std::to_string(robot.dof()) + " DOFs");
  if (arm_start.size() != na)
    throw std::invalid_argument("arm_start: expected " + std::to_string(na) + " joint values, got " + std::to_string(arm_start.size()));
  if (arm_rate_limits.size() != na)
    throw std::invalid_argument("arm_rate_limits: expected " + std::to_string(na) + " values, got " + std::to_string(arm_rate_limits.size()));
  if ((arm_rate_limits.array() <= 0).any()) throw std::invalid_argument("arm_rate_limits must be positive");
  if (tool_link < 0 || tool_link >= robot.num_links()) throw std::invalid_argument("tool_link: index out of range");
  if (std::abs(approach_dir.norm() - 1.0) > 1e-6) throw std::invalid_argument("approach_dir must be a unit vector");
  if (!(grasp_area_rmax > grasp_area_rmin) || grasp_area_rmin < 0)
    throw std::invalid_argument("grasp area: expected 0 <= rmin < rmax");
  if (!(gamma >= 0 && gamma <= 1)) throw std::invalid_argument("gamma must lie in [0, 1], got " + std::to_string(gamma));
  if (!(stroke > 0)) throw std::invalid_argument("stroke must be positive");
  if (!(base_speed_limit > 0) || !(base_yaw_rate_limit > 0)) throw std::invalid_argument("base limits must be positive");
  if (!(goal_tol_pos > 0) || !(goal_tol_yaw > 0)) throw std::invalid_argument("goal tolerances must be positive");
  rho.validate();
  if (!vary_sc && !(sc_fixed > 0)) throw std::invalid_argument("sc_fixed must be positive");
  for (const auto& b : body_spheres)
    if (b.link < 0 || b.link >= robot.num_links()) throw std::invalid_argument("body sphere: link index out of range");
  if (!start.allFinite() || !goal.allFinite() || !arm_start.allFinite() || !grasp_pose.p.allFinite())
    throw std::invalid_argument("start, goal, arm_start and grasp pose must be finite");
}

std::vector<int> default_degrees(int dof) {
  // Base x, y, phi quintic (the paper uses cubics; a cubic base cannot keep the non-holonomic
  // error below ~3 % of the path length on the Sec. VI geometry, a quintic reaches ~0.05 %),
  // arm base/shoulder/elbow quintic, wrists cubic.
  std::vector<int> d(dof, 3);
  for (int i = 0; i < std::min(dof, 6); ++i) d[i] = 5;
  return d;
}

std::vector<int> resolved_degrees(const PickupSettings& settings, int dof) {
  return settings.degrees.empty() ? default_degrees(dof) : settings.degrees;
}

namespace {
int num_vars(const Robot& robot, const PickupSettings& st) {
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  return PolyTraj(deg, 1.0).num_coeffs() + 5;
}
}  // namespace

namespace {
// Sound reachability test of the grasp position: the tool is at most R (sum of the fixed link
// offsets from the first arm joint to the tool, triangle inequality) from the first arm joint, whose
// position is fixed on the base; if even the nearest base pose in the grasping area leaves the grasp
// point farther than R, no trajectory can satisfy the grasp-pose constraint.
bool grasp_unreachable(const Robot& robot, const PickupProblem& pb, std::string& why) {
  const int first = robot.link_of_q(3);
  double reach = 0.0;
  for (int k = pb.tool_link; k >= 0 && k != first; k = robot.link(k).parent) {
    if (robot.link(k).joint_type == JointType::Prismatic) return false;  // no bound for prismatic arms
    reach += robot.link(k).joint_origin.p.norm();
  }
  RobotWorkspace ws(robot);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(robot.dof());
  robot.forward_kinematics(q.data(), ws);
  const Eigen::Vector3d j0 = ws.link_pose[first].p - robot.base().p;
  const double mount = j0.head<2>().norm();
  const double dz = pb.grasp_pose.p.z() - (robot.base().p.z() + j0.z());
  const double dxy_part = (pb.grasp_pose.p.head<2>() - pb.part_xy).norm();
  const double h = std::max(0.0, pb.grasp_area_rmin - mount - dxy_part);
  const double dmin = std::hypot(dz, h);
  if (dmin <= reach) return false;
  why = "grasp point at least " + std::to_string(dmin) + " m from the first arm joint, reach " + std::to_string(reach) + " m";
  return true;
}
}  // namespace

namespace {
// What a solved stage hands the next: its multipliers by row key (PickupConstraints::row_key) and
// its optional rows (those found between samples are not rediscovered by near_rows).
struct StageMultipliers {
  std::map<std::array<double, 5>, double> lambda;
  Eigen::VectorXd zl, zu;
  PickupRowSubset subset;
};

// bound: a run whose T ends at or above it stops the stage ("bounded"; a better solution is known).
StageResult solve_stage_warm(const Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                             const Eigen::VectorXd& x0, const StageMultipliers* warm_in, StageMultipliers* warm_out,
                             double bound = std::numeric_limits<double>::infinity());
}  // namespace

StageResult solve_stage(const Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                        const Eigen::VectorXd& x0) {
  return solve_stage_warm(robot, pb, st, stage, x0, nullptr, nullptr);
}

namespace {
StageResult solve_stage_warm(const Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                             const Eigen::VectorXd& x0, const StageMultipliers* warm_in, StageMultipliers* warm_out,
                             double bound) {
  PickupConstraints cons(robot, pb, st, stage);  // validates (throws std::invalid_argument)
  if (x0.size() != cons.num_vars())
    throw std::invalid_argument("seed: expected " + std::to_string(cons.num_vars()) + " variables, got " + std::to_string(x0.size()));
  if (!x0.allFinite()) throw std::invalid_argument("seed: values must be finite");
  const double T = x0[cons.idx_T()], T1 = x0[cons.idx_s1()] * T, T2 = x0[cons.idx_s2()] * T;
  if (!(T > 0 && x0[cons.idx_s1()] >= 0.0 && x0[cons.idx_s1()] <= x0[cons.idx_s2()] && x0[cons.idx_s2()] <= 1.0))
    throw std::invalid_argument("seed: inconsistent time ordering, expected 0 <= T1 <= T2 <= T, got T1=" +
                                std::to_string(T1) + " T2=" + std::to_string(T2) + " T=" + std::to_string(T));
  StageResult res;
  const auto t_start = std::chrono::steady_clock::now();
  const double cpu_start = thread_cpu_seconds();
  res.stage = stage;
  std::string why;
  if ((stage == 0 || stage >= 2) && grasp_unreachable(robot, pb, why)) {
    res.status = "infeasible";
    res.ipopt_status = "Not_Solved (reachability pre-check: " + why + ")";
    res.x = x0;
    res.objective = x0[cons.idx_T()];
    res.max_violation = cons.max_violation(x0);
    return res;
  }
  if ((stage == 0 || stage >= 4) && std::isnan(cons.sg_cap())) {
    res.status = "infeasible";
    res.ipopt_status = "Not_Solved (success-probability pre-check: rho < gamma = " + std::to_string(pb.gamma) +
                       " over the whole (S_g, S_c) range)";
    res.x = x0;
    res.objective = x0[cons.idx_T()];
    res.max_violation = cons.max_violation(x0);
    return res;
  }
  // Active set: the optional rows (joint positions, collisions) only where x is near them; after
  // each solve, every row of the full stage is checked (and, with collisions, the trajectory
  // between the samples, densely); rows that are violated or near join and the stage is re-solved
  // from its last solution.
  const double tol = std::max(1e-4, 10 * st.constr_viol_tol);
  const double inf = std::numeric_limits<double>::infinity();
  PickupRowSubset subset = st.active_set ? cons.near_rows(x0, st.active_joint_window, st.active_collision_window)
                                         : cons.near_rows(x0, inf, inf);  // every optional row
  Eigen::VectorXd x = x0;
  double mu = st.mu_init;
  StageMultipliers prev;  // from the last round (or the previous stage)
  if (warm_in) {
    prev = *warm_in;
    subset.merge(warm_in->subset);
    if (prev.zl.size()) mu = st.mu_resolve;
  }
  for (int round = 0;; ++round) {
    const PickupConstraints part(robot, pb, st, stage, &subset);
    Multipliers warm;
    if (prev.zl.size() == part.num_vars()) {  // carried over; the rows new in this run start at 0
      warm.zl = prev.zl;
      warm.zu = prev.zu;
      warm.lambda = Eigen::VectorXd::Zero(part.num_constraints());
      for (int r = 0; r < part.num_constraints(); ++r) {
        auto it = prev.lambda.find(part.row_key(r));
        if (it != prev.lambda.end()) warm.lambda[r] = it->second;
      }
    }
    IpoptRun run = run_ipopt(part, st, x, mu, warm.lambda.size() ? &warm : nullptr);
    if (run.mult.lambda.size() == part.num_constraints()) {
      prev.zl = run.mult.zl;
      prev.zu = run.mult.zu;
      prev.lambda.clear();
      for (int r = 0; r < part.num_constraints(); ++r) prev.lambda[part.row_key(r)] = run.mult.lambda[r];
    }
    res.iterations += run.iterations;
    res.rounds = round + 1;
    res.rows = part.num_constraints();
    if (st.print_level > 0)
      std::fprintf(stderr, "pickup stage %d round %d: %d rows (optional: %d joint, %d collision), %s, %d iterations, %.3f s, T %.3f\n",
                   stage, round + 1, part.num_constraints(), static_cast<int>(subset.joints.size()),
                   static_cast<int>(subset.collisions.size()), run.status.c_str(), run.iterations, run.seconds,
                   run.x[cons.idx_T()]);
    res.status = run.status;
    res.ipopt_status = run.ipopt_status;
    x = run.x;
    if (!run.converged) break;
    if (x[cons.idx_T()] >= bound) {
      res.status = "bounded";
      res.ipopt_status += " (T " + std::to_string(x[cons.idx_T()]) + " s, not below the best known " + std::to_string(bound) + " s)";
      break;
    }
    const bool feasible = cons.max_violation(x) <= tol;
    PickupRowSubset more;
    if (st.active_set && !feasible) more = cons.near_rows(x, st.active_joint_window, st.active_collision_window);
    if (st.dense_subdivisions > 0)
      more.merge(cons.dense_points(x, st.dense_subdivisions, 0.5 * st.collision_margin, 0.5 * st.joint_limit_margin));
    if (feasible && more.size() == 0) break;
    const int before = subset.size();
    if (st.print_level > 0) {
      std::fprintf(stderr, "  violated/near joints:");
      for (const auto& j : more.joints) std::fprintf(stderr, " %d@%d", j.joint, j.sample);
      std::fprintf(stderr, "; collisions (pair@sample or @s):");
      for (const auto& c : more.collisions) std::fprintf(stderr, " %d@%d(%.3f,%.3f,%.3f)", c.pair, c.sample, c.w[0], c.w[1], c.w[2]);
      std::fprintf(stderr, "\n");
    }
    subset.merge(more);
    if (subset.size() == before || round + 1 >= st.active_max_rounds) {
      res.status = feasible ? "violation_between_samples" : "constraint_violation";
      res.ipopt_status += " (active set: " + std::to_string(round + 1) + " rounds, " +
                          (feasible ? "the dense check between samples still fails" : "rows still violated") + ")";
      run.converged = false;
      break;
    }
    mu = st.mu_resolve;  // a warm re-solve: start near the boundary of the (mostly) active rows
  }
  res.x = x;
  // Everything of the stage: Ipopt runs, row selection, full-stage and dense checks.
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  res.cpu_seconds = thread_cpu_seconds() - cpu_start;
  res.objective = res.x[cons.idx_T()];
  res.max_violation = cons.max_violation(res.x);
  const bool converged = res.status == "solved" || res.status == "solved_acceptable";
  res.success = converged && res.max_violation <= tol;
  if (converged && !res.success) res.status = "constraint_violation";
  if (warm_out && (res.success || res.status == "bounded")) {  // (bounded: its multipliers still price the rows)
    *warm_out = prev;
    warm_out->subset = subset;
  }
  return res;
}
}  // namespace

namespace {
void fill_result(PickupResult& out, const Robot& robot, const PickupSettings& st) {
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  const int nc = PolyTraj(deg, 1.0).num_coeffs();
  out.T = out.x[nc + 2];
  out.T1 = out.x[nc] * out.T;
  out.T2 = out.x[nc + 1] * out.T;
  out.traj = PolyTraj(deg, out.T);
  out.S_g = out.x[nc + 3];
  out.S_c = out.x[nc + 4];
  for (const auto& s : out.stages) {
    out.total_seconds += s.seconds;
    out.total_cpu_seconds += s.cpu_seconds;
  }
  out.total_seconds += out.direct.seconds + out.search_seconds;
  out.total_cpu_seconds += out.direct.cpu_seconds + out.search_cpu_seconds;
}
}  // namespace

namespace {
double elapsed(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Stages 2-5 from the stage-2 seed x2 (stage 1's record is the first of `stages`), each stopped
// when its T reaches `bound`. Returns whether all succeeded; x: the last good solution.
// limit_price: per DOF, the sum of |multiplier| of its joint-position rows in the last Ipopt run
// (dT per unit of that joint's limits: how much time the limit costs).
bool run_stages_2_to_5(const Robot& robot, const PickupProblem& pb, const PickupSettings& st, const Eigen::VectorXd& x2,
                       double seed_wall, double seed_cpu, double bound, std::vector<StageResult>& stages,
                       Eigen::VectorXd& x, std::string& status, Eigen::VectorXd& limit_price) {
  StageMultipliers mult;
  limit_price = Eigen::VectorXd::Zero(robot.dof());
  auto price = [&]() {
    limit_price.setZero();
    for (const auto& [key, lambda] : mult.lambda)
      if (static_cast<int>(key[0]) == K_JPOS) limit_price[3 + static_cast<int>(key[4])] += std::abs(lambda);
  };
  for (int stage = 2; stage <= 5; ++stage) {
    // Stages 2 and 3 start cold (stage 2 from an IK seed, stage 3's new velocity rows are far
    // from satisfied); stages 4 and 5 from the previous stage's multipliers.
    const bool warm = st.warm_start_stages && stage > 3;
    if (!warm) mult = StageMultipliers();
    const auto t_seed = std::chrono::steady_clock::now();
    const double cpu_seed = thread_cpu_seconds();
    Eigen::VectorXd seed = stage == 2 ? x2 : x;
    if (stage == 3 && st.timing_seed) seed = grasp_timing_seed(robot, pb, st, x, st.timing_fraction);
    seed_wall += elapsed(t_seed);
    seed_cpu += thread_cpu_seconds() - cpu_seed;
    StageResult r = solve_stage_warm(robot, pb, st, stage, seed, &mult, &mult, bound);
    r.seconds += seed_wall;  // the stage's warm start (IK, timing) counts as the stage's time
    r.cpu_seconds += seed_cpu;
    seed_wall = seed_cpu = 0.0;
    stages.push_back(r);
    if (r.success || r.status == "bounded") price();
    if (!r.success) {
      status = r.status;
      return false;
    }
    x = r.x;
  }
  return true;
}
}  // namespace

PickupResult solve_successive(const Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                              const Eigen::VectorXd& x0) {
  PickupResult out;
  const auto t_h = std::chrono::steady_clock::now();
  const double cpu_h = thread_cpu_seconds();
  out.x = x0.size() ? x0 : heuristic_seed(robot, pb, st);
  const double seed_wall = elapsed(t_h), seed_cpu = thread_cpu_seconds() - cpu_h;  // counted in stage 1
  if (out.x.size() != num_vars(robot, st))
    throw std::invalid_argument("seed: expected " + std::to_string(num_vars(robot, st)) + " variables, got " + std::to_string(out.x.size()));
  StageResult r1 = solve_stage_warm(robot, pb, st, 1, out.x, nullptr, nullptr);
  r1.seconds += seed_wall;
  r1.cpu_seconds += seed_cpu;
  out.stages.push_back(r1);
  out.success = r1.success;
  out.status = r1.success ? "solved" : r1.status;
  if (r1.success) {
    out.x = r1.x;
    out.stages_completed = 1;
    // Stages 2-5 from up to st.arm_seeds arm configurations at T2 (PickupSettings::arm_seeds).
    // The polynomials commit early: the wrists are cubics, so a joint's value at T2 (any 2 pi
    // turn gives the same grasp) decides where its polynomial runs after T2 and which limits bind.
    // A run's joint-limit multipliers say which turn is worth a run. The IK counts as the first
    // run's stage 2; the shortest successful run is kept, the others' time goes to search_seconds.
    const auto t_ik = std::chrono::steady_clock::now();
    const double cpu_ik = thread_cpu_seconds();
    const int max_seeds = std::max(1, st.arm_seeds);
    const GraspArmSeeds g = grasp_arm_seeds(robot, pb, st, r1.x, max_seeds > 2);
    // Run order: the IK solution; its configuration with the joint whose limits cost the most time
    // turned by 2 pi; the shoulder flip; then the other turns, in the order found.
    std::vector<Eigen::VectorXd> arms = {g.arms.front()}, later(g.arms.begin() + 1, g.arms.end());
    double ik_wall = elapsed(t_ik), ik_cpu = thread_cpu_seconds() - cpu_ik;
    double best = std::numeric_limits<double>::infinity();
    auto known = [&](const Eigen::VectorXd& w) {
      for (const auto* v : {&arms, &later})
        for (const auto& a : *v)
          if ((a - w).norm() < 1e-3) return true;
      return false;
    };
    for (int k = 0; k < max_seeds; ++k) {
      if (k >= static_cast<int>(arms.size())) {
        if (later.empty()) break;
        arms.push_back(later.front());
        later.erase(later.begin());
      }
      const auto t_seed = std::chrono::steady_clock::now();
      const double cpu_seed = thread_cpu_seconds();
      const Eigen::VectorXd x2 = arm_blend_seed(robot, pb, st, g.path, arms[k]);
      ik_wall += elapsed(t_seed);
      ik_cpu += thread_cpu_seconds() - cpu_seed;
      if (st.print_level > 0) {
        std::fprintf(stderr, "arm seed %d at T2:", k);
        for (int j = 3; j < arms[k].size(); ++j) std::fprintf(stderr, " %.2f", arms[k][j]);
        std::fprintf(stderr, "\n");
      }
      std::vector<StageResult> stages = {r1};
      Eigen::VectorXd x = r1.x, price;
      std::string status;
      // Shorter than the best by more than Ipopt's tolerance, or it is not kept.
      const bool ok = run_stages_2_to_5(robot, pb, st, x2, ik_wall, ik_cpu, best * (1.0 - 1e-4), stages, x, status, price);
      ik_wall = ik_cpu = 0.0;
      if (stages.size() >= 3 && max_seeds > 1) {  // a trajectory with the grasp velocity: where it meets limits
        std::vector<Eigen::VectorXd> turns;
        for (const Eigen::VectorXd& w : wound_arm_configurations(robot, pb, st, arms[k], stages.back().x, price))
          if (!known(w)) turns.push_back(w);
        if (k == 0 && !turns.empty()) {  // the dearest turn of the IK solution runs next
          arms.push_back(turns.front());
          turns.erase(turns.begin());
        }
        later.insert(later.end(), turns.begin(), turns.end());
      }
      ++out.arm_seeds_tried;
      out.arm_seed_T.push_back(ok ? x[num_vars(robot, st) - 3] : std::numeric_limits<double>::quiet_NaN());
      const bool keep = k == 0 || (ok && (!out.success || out.arm_seed_T.back() < best));
      auto count_search = [&](const std::vector<StageResult>& v) {
        for (size_t i = 1; i < v.size(); ++i) {
          out.search_seconds += v[i].seconds;
          out.search_cpu_seconds += v[i].cpu_seconds;
        }
      };
      if (!keep) {
        count_search(stages);
        continue;
      }
      if (k > 0) count_search(out.stages);  // the records replaced are those of a run not kept
      out.stages = stages;
      out.x = x;
      out.success = ok;
      out.status = ok ? "solved" : status;
      out.stages_completed = static_cast<int>(stages.size()) - (ok ? 0 : 1);
      out.arm_seed_chosen = k;
      if (ok) best = out.arm_seed_T.back();
    }
  }
  // The direct track: all constraints at once from the stage-1 solution (a feasible base path with
  // the arm at rest). Stages 2 and 3 commit the arm to one IK branch and grasp timing; this solve
  // is free to choose both, and the shorter of the two solutions is returned.
  if (st.direct_track && out.stages_completed >= 1) {
    PickupSettings sd = st;
    sd.max_iter = std::min(st.max_iter, st.direct_max_iter);
    const double staged = out.success ? out.stages.back().objective : std::numeric_limits<double>::infinity();
    // Shorter by more than Ipopt's tolerance (a tie keeps the successive solution).
    out.direct = solve_stage_warm(robot, pb, sd, 0, out.stages.front().x, nullptr, nullptr, staged * (1.0 - 1e-4));
    if (out.direct.success && out.direct.objective < staged * (1.0 - 1e-4)) {
      out.x = out.direct.x;
      out.direct_chosen = true;
      out.success = true;
      out.status = "solved";
      out.stages_completed = 5;
    }
  }
  fill_result(out, robot, st);
  return out;
}

PickupResult solve_single_shot(const Robot& robot, const PickupProblem& pb, const PickupSettings& st) {
  PickupResult out;
  const Eigen::VectorXd seed = random_seed(robot, pb, st);
  StageResult r = solve_stage(robot, pb, st, 0, seed);
  out.stages.push_back(r);
  out.status = r.status;
  out.success = r.success;
  out.stages_completed = r.success ? 5 : 0;
  out.x = r.success ? r.x : seed;
  fill_result(out, robot, st);
  return out;
}

}  // namespace pickplan
