#include "pickplan/omg/omg_loop.hpp"

#include <chrono>
#include <cmath>
#include <ctime>
#include <limits>
#include <stdexcept>
#include <string>

#include "pickplan/core/errors.hpp"

namespace pickplan::omg {

namespace {

double now(StageClock clock) {
  if (clock == StageClock::thread_cpu) {
    timespec ts{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
  }
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Adds the seconds from construction to destruction to *sink.
class StageTimer {
 public:
  StageTimer(StageClock clock, double* sink) : clock_(clock), sink_(sink), start_(now(clock)) {}
  ~StageTimer() { *sink_ += now(clock_) - start_; }

 private:
  StageClock clock_;
  double* sink_;
  double start_;
};

void check_settings(const OmgLoopSettings& s) {
  if (s.iterations < 1 || s.isf_steps < 0 || s.cost_time_stride < 1 || s.cost_point_stride < 1 ||
      s.min_iterations < 0 || s.check_every < 1)
    throw std::invalid_argument(
        "OMG loop settings: iterations >= 1, isf_steps >= 0, strides >= 1, min_iterations >= 0 "
        "and check_every >= 1 required");
}

}  // namespace

GoalBook::GoalBook(const core::Robot& robot, int hand_link, const Trajectory& goals, std::vector<Trajectory> tails,
                   std::vector<int> grasp_index)
    : robot_(robot), hand_(hand_link), fk_(robot), tails_(std::move(tails)), origin_(std::move(grasp_index)) {
  const long G = goals.rows();
  if (G < 1) throw std::invalid_argument("goal book: no goals");
  if (hand_ < 0 || hand_ >= robot.num_links()) throw std::invalid_argument("goal book: hand link out of range");
  core::require_size("goal book: goal columns", robot.dof(), goals.cols(), "joint values");
  core::require_size("goal book: tails", G, static_cast<long>(tails_.size()), "tails (one per goal)");
  core::require_size("goal book: grasp indices", G, static_cast<long>(origin_.size()), "entries (one per goal)");
  core::require_finite("goal book: goals", goals.data(), goals.size());
  const long m = tails_.front().rows();
  for (const Trajectory& t : tails_) {
    if (t.rows() != m || t.rows() < 1)
      throw std::invalid_argument("goal book: every tail needs the same number (>= 1) of rows");
    core::require_size("goal book: tail columns", robot.dof(), t.cols(), "joint values");
    core::require_finite("goal book: tails", t.data(), t.size());
  }
  for (long g = 0; g < G; ++g) {
    goals_.push_back(goals.row(g).transpose());
    origin_goal_.push_back(static_cast<int>(g));
  }
}

bool GoalBook::on_goal(const Trajectory& xi, int g) const {
  const Trajectory& t = tails_[g];
  return (xi.bottomRows(t.rows()) - t).cwiseAbs().maxCoeff() <= 1e-9;  // NaN is never on a goal
}

bool GoalBook::is_refined(int g) const {
  for (const auto& kv : refined_copy_)
    if (kv.second == g) return true;
  return false;
}

Eigen::Vector3d GoalBook::hand_position(const Eigen::VectorXd& q) {
  robot_.forward_kinematics(q.data(), fk_);
  return fk_.link_pose[hand_].p;
}

Trajectory GoalBook::goal_matrix() const {
  Trajectory out(size(), robot_.dof());
  for (int g = 0; g < size(); ++g) out.row(g) = goals_[g].transpose();
  return out;
}

std::pair<int, bool> GoalBook::refine(int g, const GraspRefiner& refiner, int steps, double max_shift) {
  const Eigen::VectorXd q_ref = refiner.refine(goals_[g], steps);
  const int source = origin_goal_[g];
  if (!grasp_hand_.count(source)) grasp_hand_[source] = hand_position(goals_[source]);
  const double shift = (hand_position(q_ref) - grasp_hand_[source]).norm();
  if ((q_ref - goals_[g]).cwiseAbs().maxCoeff() == 0 || shift > max_shift) {
    stalled_.insert(g);  // deterministic: refining again would give the same
    return {g, false};
  }
  Trajectory shifted = tails_[g];
  shifted.rowwise() += (q_ref - goals_[g]).transpose();  // keep the approach's shape
  // The approach is pinned from here on: shifted past a joint limit it can never be executed (an IK tail
  // within 1 mrad of panda_joint2's limit, shifted 1.5 mrad beyond it, was refused by PyBullet).
  const Eigen::RowVectorXd lo = robot_.lower_limits().transpose(), hi = robot_.upper_limits().transpose();
  if (((shifted.rowwise() - lo).array() < 0).any() || ((shifted.rowwise() - hi).array() > 0).any()) {
    stalled_.insert(g);
    return {g, false};
  }
  if (is_refined(g)) {
    goals_[g] = q_ref, tails_[g] = shifted;
    return {g, false};
  }
  const auto copy = refined_copy_.find(g);
  if (copy != refined_copy_.end()) {
    goals_[copy->second] = q_ref, tails_[copy->second] = shifted;
    return {copy->second, false};
  }
  goals_.push_back(q_ref);
  tails_.push_back(shifted);
  origin_.push_back(origin_[g]);
  origin_goal_.push_back(g);
  refined_copy_[g] = size() - 1;
  return {size() - 1, true};
}

namespace {

class Loop {
 public:
  Loop(const ChompProblem& problem, const GraspRefiner* refiner, GoalBook& book, const Eigen::VectorXd& q0,
       const Eigen::VectorXd& blend, const OmgLoopSettings& s, const WarmStart* warm, const PlanCheck* check)
      : problem_(problem),
        refiner_(refiner),
        book_(book),
        q0_(q0),
        blend_(blend),
        s_(s),
        warm_(warm),
        check_(check),
        ws_(problem),
        policy_(s.selection) {}

  OmgLoopResult run();

 private:
  Trajectory initial(int g) const {
    Trajectory xi(problem_.settings().n, q0_.size());
    const Eigen::RowVectorXd d = (book_.goal(g) - q0_).transpose();
    for (long t = 0; t < xi.rows(); ++t) xi.row(t) = q0_.transpose() + blend_[t] * d;
    return xi;
  }
  Eigen::VectorXd estimates(const Trajectory& xi, int iteration);
  bool succeeds(Trajectory& xi, int g, int iterations, TrajectoryMetrics& metrics);
  double now() const { return omg::now(s_.clock); }

  const ChompProblem& problem_;
  const GraspRefiner* refiner_;
  GoalBook& book_;
  const Eigen::VectorXd& q0_;
  const Eigen::VectorXd& blend_;
  const OmgLoopSettings& s_;
  const WarmStart* warm_;
  const PlanCheck* check_;
  ChompWorkspace ws_;
  SelectionPolicy policy_;
  OmgStageSeconds seconds_;
};

Eigen::VectorXd Loop::estimates(const Trajectory& xi, int iteration) {
  StageTimer timer(s_.clock, &seconds_.costs);
  const Trajectory goals = book_.goal_matrix();
  Eigen::VectorXd c(goals.rows());
  if (policy_.cost_kind() == CostKind::distance) {  // Proj: distance of the free end point to each goal
    Trajectory grad, u;
    problem_.objective(xi, q0_, iteration, &grad, ws_);
    problem_.solve_A(grad, u);
    const Eigen::RowVectorXd free_end = xi.row(xi.rows() - 1) - problem_.settings().step_size * u.row(u.rows() - 1);
    Eigen::RowVectorXd sq(goals.cols());
    for (long g = 0; g < goals.rows(); ++g) {
      sq = (goals.row(g) - free_end).cwiseAbs2();
      c[g] = std::sqrt(numpy_sum(sq.data(), sq.size()));
    }
  } else {
    problem_.goal_costs(xi, q0_, iteration, s_.iterations, goals, s_.cost_time_stride, s_.cost_point_stride, c.data(),
                        ws_);
  }
  const double norm = c.norm();
  if (norm > 0) c /= norm;
  return c;
}

bool Loop::succeeds(Trajectory& xi, int g, int iterations, TrajectoryMetrics& metrics) {
  StageTimer timer(s_.clock, &seconds_.metrics);
  Trajectory cand = xi;
  if (!book_.on_goal(xi, g)) problem_.step(cand, q0_, &book_.tail(g), iterations, ws_);
  // A failing check's metrics are dropped (the returned trajectory is measured in full): stop early.
  metrics = evaluate_trajectory(problem_, q0_, cand, s_.metrics, /*stop_at_failure=*/true);
  if (!metrics.success || (check_ && !(*check_)(cand))) return false;
  xi = std::move(cand);
  return true;
}

OmgLoopResult Loop::run() {
  OmgLoopResult r;
  const int m = book_.tail_length();
  Trajectory xi = warm_ ? warm_->initial : initial(0);
  // The initial estimates pick the first goal and seed the policy; a warm start on a given goal needs
  // them only when it does not stand as it is (below), so they wait until then.
  const bool warm_goal = warm_ && warm_->initial_goal >= 0;
  Eigen::VectorXd c0;
  int g = 0;
  if (warm_goal) {
    g = warm_->initial_goal;
  } else {
    c0 = estimates(xi, 0);
    for (int j = 1; j < c0.size(); ++j)  // the initial goal: best by the initial estimate (np.argmin)
      if (c0[j] < c0[g]) g = j;
  }
  if (!warm_) xi = initial(g);
  // A warm start already on its goal's approach (nothing moved there) may stand as it is; one whose
  // goal moved gets the new approach and is optimized (a jump onto it may pass the test, but is a jump).
  const bool unchanged = warm_ && book_.on_goal(xi, g);
  xi.bottomRows(m) = book_.tail(g);
  r.initial_grasp = book_.origin(g);
  bool have_metrics = false;
  if (unchanged && s_.pre_terminate) {  // still good: kept as it is
    StageTimer timer(s_.clock, &seconds_.metrics);
    r.metrics = evaluate_trajectory(problem_, q0_, xi, s_.metrics, /*stop_at_failure=*/true);
    have_metrics = r.metrics.success && (!check_ || (*check_)(xi));
  }
  if (!have_metrics) {
    if (warm_goal) c0 = warm_->initial_costs.size() ? warm_->initial_costs : estimates(warm_->initial, 0);
    policy_.reset(book_.size(), s_.iterations, &c0);
  }
  for (int i = 0; i < s_.iterations && !have_metrics; ++i) {
    r.iterations = i + 1;
    {
      StageTimer timer(s_.clock, &seconds_.chomp);
      r.objective.push_back(problem_.step(xi, q0_, &book_.tail(g), i, ws_).before.total);
    }
    r.costs.push_back(estimates(xi, i + 1));
    int next;
    {
      StageTimer timer(s_.clock, &seconds_.selection);
      r.p.push_back(policy_.update(r.costs.back()));
      next = policy_.select();
    }
    if (refiner_ && !book_.stalled(next)) {
      StageTimer timer(s_.clock, &seconds_.isf);
      const auto [followed, added] = book_.refine(next, *refiner_, s_.isf_steps, s_.isf_max_shift);
      next = followed;
      if (added) policy_.add_goal();
    }
    r.switches += next != g;
    r.goals_chosen.push_back(next);
    // On a switch the tail stays: the next CHOMP-Proj step's offset term (eq. 7) moves the whole
    // trajectory smoothly onto the new goal.
    g = next;
    if (s_.pre_terminate && r.iterations >= s_.min_iterations && r.iterations % s_.check_every == 0) {
      have_metrics = succeeds(xi, g, r.iterations, r.metrics);
      if (have_metrics) break;
    }
  }
  if (!book_.on_goal(xi, g)) {  // the last selection (a switch or a refined goal): project onto it
    StageTimer timer(s_.clock, &seconds_.chomp);
    problem_.step(xi, q0_, &book_.tail(g), r.iterations, ws_);
  }
  {
    StageTimer timer(s_.clock, &seconds_.metrics);
    if (!have_metrics) r.metrics = evaluate_trajectory(problem_, q0_, xi, s_.metrics);
    r.grasp_cost = refiner_ ? refiner_->cost(xi.row(xi.rows() - 1).transpose(), nullptr).total
                            : std::numeric_limits<double>::quiet_NaN();
  }
  r.xi = std::move(xi);
  r.goal = g;
  r.grasp_index = book_.origin(g);
  r.goal_source = book_.origin_goal(g);
  r.refined = book_.is_refined(g);
  r.goal_set_size = book_.size();
  r.seconds = seconds_;
  return r;
}

}  // namespace

OmgLoopResult run_omg_loop(const ChompProblem& problem, const GraspRefiner* refiner, int hand_link,
                           const Eigen::VectorXd& q0, const Trajectory& goals, const std::vector<Trajectory>& tails,
                           const std::vector<int>& grasp_index, const Eigen::VectorXd& blend,
                           const OmgLoopSettings& settings, const WarmStart* warm, const PlanCheck* check) {
  check_settings(settings);
  core::require_size("OMG loop: initialization blend", problem.settings().n, blend.size(),
                     "entries (one per waypoint)");
  core::require_finite("OMG loop: initialization blend", blend.data(), blend.size());
  problem.robot().check_configuration(q0.data(), q0.size());
  GoalBook book(problem.robot(), hand_link, goals, tails, grasp_index);
  if (book.tail_length() > problem.settings().n)
    throw std::invalid_argument("OMG loop: tails longer than the trajectory");
  if (warm) {
    core::require_size("OMG loop: warm start", problem.settings().n, warm->initial.rows(), "waypoints");
    core::require_size("OMG loop: warm start", q0.size(), warm->initial.cols(), "joints per waypoint");
    core::require_finite("OMG loop: warm start", warm->initial.data(), warm->initial.size());
    if (warm->initial_goal < -1 || warm->initial_goal >= book.size())
      throw std::invalid_argument("OMG loop: warm start goal " + std::to_string(warm->initial_goal) +
                                  " is not one of the " + std::to_string(book.size()) + " goals");
    if (warm->initial_costs.size() && warm->initial_costs.size() != book.size())
      throw std::invalid_argument("OMG loop: warm start costs: expected one per goal (" + std::to_string(book.size()) +
                                  "), got " + std::to_string(warm->initial_costs.size()));
    core::require_finite("OMG loop: warm start costs", warm->initial_costs.data(), warm->initial_costs.size());
  }
  return Loop(problem, refiner, book, q0, blend, settings, warm, check).run();
}

}  // namespace pickplan::omg
