// Ipopt driver of the pick-up NLP: the five stages of successive refinement (Sec. V-B) with
// their active-set rounds and warm starts, and the single-shot baseline. Ipopt + MUMPS is not
// thread-safe: one solve at a time per process.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <stdexcept>
#include <string>

#include "nlp_detail.hpp"
#include "pickplan/pickup/nlp.hpp"
#include "run_limits.hpp"

namespace pickplan::pickup {
using namespace detail;

namespace {
int num_vars(const core::Robot& robot, const PickupSettings& st) {
  const std::vector<int> deg = resolved_degrees(st, robot.dof());
  return PolyTraj(deg, 1.0).num_coeffs() + 5;
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
StageResult solve_stage_warm(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                             const Eigen::VectorXd& x0, const StageMultipliers* warm_in, StageMultipliers* warm_out,
                             double bound = std::numeric_limits<double>::infinity(),
                             const RunLimits& limits = RunLimits());
}  // namespace

StageResult solve_stage(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                        const Eigen::VectorXd& x0) {
  RunLimits limits;
  limits.deadline = deadline_of(st);
  return solve_stage_warm(robot, pb, st, stage, x0, nullptr, nullptr, std::numeric_limits<double>::infinity(), limits);
}

namespace {
void check_seed(const PickupConstraints& cons, const Eigen::VectorXd& x0) {
  if (x0.size() != cons.num_vars())
    throw std::invalid_argument("seed: expected " + std::to_string(cons.num_vars()) + " variables, got " +
                                std::to_string(x0.size()));
  if (!x0.allFinite()) throw std::invalid_argument("seed: values must be finite");
  const double T = x0[cons.idx_T()], T1 = x0[cons.idx_s1()] * T, T2 = x0[cons.idx_s2()] * T;
  if (!(T > 0 && x0[cons.idx_s1()] >= 0.0 && x0[cons.idx_s1()] <= x0[cons.idx_s2()] && x0[cons.idx_s2()] <= 1.0))
    throw std::invalid_argument("seed: inconsistent time ordering, expected 0 <= T1 <= T2 <= T, got T1=" +
                                std::to_string(T1) + " T2=" + std::to_string(T2) + " T=" + std::to_string(T));
}

// The stage's pre-checks: true (res infeasible, at the seed) when the grasp is out of reach or the
// success probability cannot reach gamma.
bool fails_prechecks(const core::Robot& robot, const PickupProblem& pb, const PickupConstraints& cons, int stage,
                     const Eigen::VectorXd& x0, StageResult& res) {
  std::string why;
  if ((stage == 0 || stage >= 2) && grasp_unreachable(robot, pb, why)) {
    res.ipopt_status = "Not_Solved (reachability pre-check: " + why + ")";
  } else if ((stage == 0 || stage >= 4) && std::isnan(cons.sg_cap())) {
    res.ipopt_status = "Not_Solved (success-probability pre-check: rho < gamma = " + std::to_string(pb.gamma) +
                       " over the whole (S_g, S_c) range)";
  } else {
    return false;
  }
  res.status = SolveStatus::infeasible;
  res.x = x0;
  res.objective = x0[cons.idx_T()];
  res.max_violation = cons.max_violation(x0);
  return true;
}

// The previous run's multipliers for this run's rows (by row key; rows new in this run start at 0);
// empty when the variables differ.
Multipliers carried_multipliers(const PickupConstraints& part, const StageMultipliers& prev) {
  Multipliers warm;
  if (prev.zl.size() == part.num_vars()) {
    warm.zl = prev.zl;
    warm.zu = prev.zu;
    warm.lambda = Eigen::VectorXd::Zero(part.num_constraints());
    for (int r = 0; r < part.num_constraints(); ++r) {
      auto it = prev.lambda.find(part.row_key(r));
      if (it != prev.lambda.end()) warm.lambda[r] = it->second;
    }
  }
  return warm;
}

void keep_multipliers(const PickupConstraints& part, const Multipliers& mult, StageMultipliers& prev) {
  prev.zl = mult.zl;
  prev.zu = mult.zu;
  prev.lambda.clear();
  for (int r = 0; r < part.num_constraints(); ++r) prev.lambda[part.row_key(r)] = mult.lambda[r];
}

// The optional rows a round adds: near or violated ones when x is infeasible (active set), and the
// instants between samples that the dense check finds.
PickupRowSubset rows_to_add(const PickupConstraints& cons, const PickupSettings& st, const Eigen::VectorXd& x,
                            bool feasible) {
  PickupRowSubset more;
  if (st.active_set && !feasible) more = cons.near_rows(x, st.active_joint_window, st.active_collision_window);
  if (st.dense_subdivisions > 0)
    more.merge(cons.dense_points(x, st.dense_subdivisions, 0.5 * st.collision_margin, 0.5 * st.joint_limit_margin));
  return more;
}

void print_round(int stage, int round, const PickupConstraints& part, const PickupRowSubset& subset,
                 const IpoptRun& run, double T) {
  std::fprintf(
      stderr,
      "pickup stage %d round %d: %d rows (optional: %d joint, %d collision), %s, %d iterations, %.3f s, T %.3f\n",
      stage, round + 1, part.num_constraints(), static_cast<int>(subset.joints.size()),
      static_cast<int>(subset.collisions.size()), to_string(run.status), run.iterations, run.seconds, T);
}

void print_new_rows(const PickupRowSubset& more) {
  std::fprintf(stderr, "  violated/near joints:");
  for (const auto& j : more.joints) std::fprintf(stderr, " %d@%d", j.joint, j.sample);
  std::fprintf(stderr, "; collisions (pair@sample or @s):");
  for (const auto& c : more.collisions)
    std::fprintf(stderr, " %d@%d(%.3f,%.3f,%.3f)", c.pair, c.sample, c.w[0], c.w[1], c.w[2]);
  std::fprintf(stderr, "\n");
}

StageResult solve_stage_warm(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                             const Eigen::VectorXd& x0, const StageMultipliers* warm_in, StageMultipliers* warm_out,
                             double bound, const RunLimits& limits) {
  PickupConstraints cons(robot, pb, st, stage);  // validates (throws std::invalid_argument)
  check_seed(cons, x0);
  StageResult res;
  const auto t_start = std::chrono::steady_clock::now();
  const double cpu_start = thread_cpu_seconds();
  res.stage = stage;
  if (fails_prechecks(robot, pb, cons, stage, x0, res)) return res;
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
    const Multipliers warm = carried_multipliers(part, prev);
    PickupSettings sr = st;  // this run's time left
    if (limits.expired()) {
      res.status = SolveStatus::time_limit;
      res.ipopt_status = "Not_Solved (the time limit ran out)";
      break;
    }
    limits.start();
    sr.time_limit = limits.seconds_left();
    IpoptRun run = run_ipopt(part, sr, x, mu, warm.lambda.size() ? &warm : nullptr);
    limits.count(run.seconds, run.iterations, run.status == SolveStatus::time_limit);
    if (run.mult.lambda.size() == part.num_constraints()) keep_multipliers(part, run.mult, prev);
    res.iterations += run.iterations;
    res.rounds = round + 1;
    res.rows = part.num_constraints();
    if (st.print_level > 0) print_round(stage, round, part, subset, run, run.x[cons.idx_T()]);
    res.status = run.status;
    res.ipopt_status = run.ipopt_status;
    x = run.x;
    if (!run.converged) break;
    if (x[cons.idx_T()] >= bound) {
      res.status = SolveStatus::bounded;
      res.ipopt_status +=
          " (T " + std::to_string(x[cons.idx_T()]) + " s, not below the best known " + std::to_string(bound) + " s)";
      break;
    }
    const bool feasible = cons.max_violation(x) <= tol;
    const PickupRowSubset more = rows_to_add(cons, st, x, feasible);
    if (feasible && more.size() == 0) break;
    const int before = subset.size();
    if (st.print_level > 0) print_new_rows(more);
    subset.merge(more);
    if (subset.size() == before || round + 1 >= st.active_max_rounds) {
      res.status = feasible ? SolveStatus::violation_between_samples : SolveStatus::constraint_violation;
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
  const bool converged = res.status == SolveStatus::solved || res.status == SolveStatus::solved_acceptable;
  res.success = converged && res.max_violation <= tol;
  if (converged && !res.success) res.status = SolveStatus::constraint_violation;
  if (warm_out &&
      (res.success || res.status == SolveStatus::bounded)) {  // (bounded: its multipliers still price the rows)
    *warm_out = prev;
    warm_out->subset = subset;
  }
  return res;
}
}  // namespace

namespace {
void fill_result(PickupResult& out, const core::Robot& robot, const PickupSettings& st) {
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
bool run_stages_2_to_5(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                       const Eigen::VectorXd& x2, double seed_wall, double seed_cpu, double bound,
                       const RunLimits& limits, std::vector<StageResult>& stages, Eigen::VectorXd& x,
                       SolveStatus& status, Eigen::VectorXd& limit_price) {
  StageMultipliers mult;
  limit_price = Eigen::VectorXd::Zero(robot.dof());
  auto price = [&]() {
    limit_price.setZero();
    for (const auto& [key, lambda] : mult.lambda)
      if (static_cast<int>(key[0]) == K_JPOS) limit_price[3 + static_cast<int>(key[4])] += std::abs(lambda);
  };
  for (int stage = 2; stage <= 5; ++stage) {
    if (limits.expired()) {  // before the stage's seed (IK, grasp timing): no step starts after the deadline
      StageResult r;
      r.stage = stage;
      r.status = status = SolveStatus::time_limit;
      r.ipopt_status = "Not_Solved (the time limit ran out)";
      r.x = stage == 2 ? x2 : x;
      r.objective = r.x[r.x.size() - 3];  // T
      stages.push_back(r);
      return false;
    }
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
    StageResult r = solve_stage_warm(robot, pb, st, stage, seed, &mult, &mult, bound, limits);
    r.seconds += seed_wall;  // the stage's warm start (IK, timing) counts as the stage's time
    r.cpu_seconds += seed_cpu;
    seed_wall = seed_cpu = 0.0;
    stages.push_back(r);
    if (r.success || r.status == SolveStatus::bounded) price();
    if (!r.success) {
      status = r.status;
      return false;
    }
    x = r.x;
  }
  return true;
}
}  // namespace

namespace {
// solve_successive's clock: false once the deadline is near (or a run was cut), and from then on.
bool time_left(const RunLimits& limits, bool& timed_out) {
  if (limits.expired()) timed_out = true;
  return !timed_out;
}

// The time of stages 2-5 of a run not kept (v[0] is stage 1, shared by every run).
void add_search_time(PickupResult& out, const std::vector<StageResult>& v) {
  for (size_t i = 1; i < v.size(); ++i) {
    out.search_seconds += v[i].seconds;
    out.search_cpu_seconds += v[i].cpu_seconds;
  }
}

void print_arm_seed(int k, const Eigen::VectorXd& arm) {
  std::fprintf(stderr, "arm seed %d at T2:", k);
  for (int j = 3; j < arm.size(); ++j) std::fprintf(stderr, " %.2f", arm[j]);
  std::fprintf(stderr, "\n");
}

// Stages 2-5 from up to st.arm_seeds arm configurations at T2 (PickupSettings::arm_seeds), after
// the stage-1 solution r1; the shortest successful run goes to out.
void search_arm_seeds(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                      const StageResult& r1, const RunLimits& limits, PickupResult& out, bool& timed_out) {
  // The polynomials commit early: the wrists are cubics, so a joint's value at T2 (any 2 pi
  // turn gives the same grasp) decides where its polynomial runs after T2 and which limits bind.
  // A run's joint-limit multipliers say which turn is worth a run. The IK counts as the first
  // run's stage 2; the shortest successful run is kept, the others' time goes to search_seconds.
  const auto t_ik = std::chrono::steady_clock::now();
  const double cpu_ik = thread_cpu_seconds();
  const int max_seeds = std::max(1, st.arm_seeds);
  const GraspArmSeeds g = grasp_arm_seeds(robot, pb, st, r1.x, max_seeds > 2);
  // Run order: the IK solution; its configuration with the joint whose limits cost the most time
  // turned by 2 pi; the other IK branches (shoulder, elbow, wrist flips, then combinations); then
  // the other turns, in the order found.
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
    if (k > 0 && !time_left(limits, timed_out)) break;
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
    if (st.print_level > 0) print_arm_seed(k, arms[k]);
    std::vector<StageResult> stages = {r1};
    Eigen::VectorXd x = r1.x, price;
    SolveStatus status = SolveStatus::not_run;
    // Shorter than the best by more than Ipopt's tolerance, or it is not kept.
    const bool ok =
        run_stages_2_to_5(robot, pb, st, x2, ik_wall, ik_cpu, best * (1.0 - 1e-4), limits, stages, x, status, price);
    ik_wall = ik_cpu = 0.0;
    if (status == SolveStatus::time_limit) timed_out = true;
    if (stages.size() >= 3 && max_seeds > 1 &&
        time_left(limits, timed_out)) {  // a trajectory with the grasp velocity: where it meets limits
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
    if (!keep) {
      add_search_time(out, stages);
      continue;
    }
    if (k > 0) add_search_time(out, out.stages);  // the records replaced are those of a run not kept
    out.stages = stages;
    out.x = x;
    out.success = ok;
    out.status = ok ? SolveStatus::solved : status;
    out.stages_completed = static_cast<int>(stages.size()) - (ok ? 0 : 1);
    out.arm_seed_chosen = k;
    if (ok) best = out.arm_seed_T.back();
  }
}

// The direct track: all constraints at once from the stage-1 solution (a feasible base path with
// the arm at rest). Stages 2 and 3 commit the arm to one IK branch and grasp timing; this solve is
// free to choose both, and the shorter of the two solutions is returned.
void try_direct_track(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                      const RunLimits& limits, PickupResult& out, bool& timed_out) {
  PickupSettings sd = st;
  sd.max_iter = std::min(st.max_iter, st.direct_max_iter);
  const double staged = out.success ? out.stages.back().objective : std::numeric_limits<double>::infinity();
  // Shorter by more than Ipopt's tolerance (a tie keeps the successive solution).
  out.direct =
      solve_stage_warm(robot, pb, sd, 0, out.stages.front().x, nullptr, nullptr, staged * (1.0 - 1e-4), limits);
  if (out.direct.status == SolveStatus::time_limit) timed_out = true;
  if (out.direct.success && out.direct.objective < staged * (1.0 - 1e-4)) {
    out.x = out.direct.x;
    out.direct_chosen = true;
    out.success = true;
    out.status = SolveStatus::solved;
    out.stages_completed = 5;
  }
}
}  // namespace

PickupResult solve_successive(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                              const Eigen::VectorXd& x0) {
  PickupResult out;
  const auto t_h = std::chrono::steady_clock::now();
  const double cpu_h = thread_cpu_seconds();
  RunLimits limits;
  limits.deadline = deadline_of(st);
  bool timed_out = false;  // a run was cut or skipped by the time limit
  out.x = x0.size() ? x0 : heuristic_seed(robot, pb, st);
  const double seed_wall = elapsed(t_h), seed_cpu = thread_cpu_seconds() - cpu_h;  // counted in stage 1
  if (out.x.size() != num_vars(robot, st))
    throw std::invalid_argument("seed: expected " + std::to_string(num_vars(robot, st)) + " variables, got " +
                                std::to_string(out.x.size()));
  StageResult r1 =
      solve_stage_warm(robot, pb, st, 1, out.x, nullptr, nullptr, std::numeric_limits<double>::infinity(), limits);
  r1.seconds += seed_wall;
  r1.cpu_seconds += seed_cpu;
  out.stages.push_back(r1);
  timed_out = r1.status == SolveStatus::time_limit;
  out.success = r1.success;
  out.status = r1.success ? SolveStatus::solved : r1.status;
  if (r1.success) {
    out.x = r1.x;
    out.stages_completed = 1;
  }
  if (r1.success && !time_left(limits, timed_out))
    out.success = false;  // stage 1 only: not a plan (status time_limit below)
  if (r1.success && !timed_out) search_arm_seeds(robot, pb, st, r1, limits, out, timed_out);
  if (st.direct_track && out.stages_completed >= 1 && time_left(limits, timed_out))
    try_direct_track(robot, pb, st, limits, out, timed_out);
  // The budget ran out somewhere: say so; success still tells whether x is a feasible solution.
  if (timed_out) out.status = SolveStatus::time_limit;
  fill_result(out, robot, st);
  return out;
}

PickupResult solve_single_shot(const core::Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                               const Eigen::VectorXd& x0) {
  PickupResult out;
  const Eigen::VectorXd seed = x0.size() ? x0 : random_seed(robot, pb, st);
  StageResult r = solve_stage(robot, pb, st, 0, seed);
  out.stages.push_back(r);
  out.status = r.status;
  out.success = r.success;
  out.stages_completed = r.success ? 5 : 0;
  out.x = r.success ? r.x : seed;
  fill_result(out, robot, st);
  return out;
}

}  // namespace pickplan::pickup