// RRT-Connect with a goal forest, shortcutting and the bounded-motion edge check.
#include "pickplan/omg/rrt_connect.hpp"

#include <algorithm>
#include <cmath>
#include <deque>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "pickplan/core/errors.hpp"

namespace pickplan::omg {

MotionBound::MotionBound(const geometry::CollisionChecker& checker) {
  const core::Robot& robot = checker.robot();
  const std::vector<double> own = checker.link_reach();
  // reach[l]: farthest distance from link l's origin to any geometry of l or its descendants.
  // Parents precede children in the link list (FK's order), so one backward pass suffices.
  std::vector<double> reach(own);
  for (int l = robot.num_links() - 1; l > 0; --l) {
    const core::Link& link = robot.link(l);
    if (link.parent < 0) continue;
    double travel = 0.0;  // a prismatic joint may carry its child this far from its origin
    if (link.joint_type == core::JointType::Prismatic) {
      const int q = link.q_index >= 0 ? link.q_index : link.mimic.source_q;
      if (q >= 0) {
        const double lo = robot.lower_limits()[q], hi = robot.upper_limits()[q];
        travel = std::isfinite(lo) && std::isfinite(hi) ? std::max(std::abs(lo), std::abs(hi)) : 1e3;
      }
    }
    reach[link.parent] = std::max(reach[link.parent], link.joint_origin.p.norm() + travel + reach[l]);
  }
  factors_ = Eigen::VectorXd::Zero(robot.dof());
  for (int l = 0; l < robot.num_links(); ++l) {
    const core::Link& link = robot.link(l);
    if (link.joint_type == core::JointType::Fixed) continue;
    const int q = link.q_index >= 0 ? link.q_index : link.mimic.source_q;
    if (q < 0) continue;
    const double m = link.q_index >= 0 ? 1.0 : std::abs(link.mimic.multiplier);
    // A rotation by dq moves a point r from the axis by at most r |dq|; a translation moves all by |dq|.
    factors_[q] += m * (link.joint_type == core::JointType::Prismatic ? 1.0 : reach[l]);
  }
}

double MotionBound::bound(const double* a, const double* b) const {
  double m = 0.0;
  for (int j = 0; j < factors_.size(); ++j) m += factors_[j] * std::abs(b[j] - a[j]);
  return m;
}

int MotionBound::steps(const double* a, const double* b, double resolution) const {
  const double n = std::ceil(bound(a, b) / resolution);
  return static_cast<int>(std::clamp(n, 1.0, 1e6));
}

namespace {

using Clock = std::chrono::steady_clock;

struct Tree {
  int dof;
  std::vector<double> q;       // nodes, row-major
  std::vector<int> parent;     // -1 for a root
  std::vector<int> root_goal;  // the goal row a node descends from (goal trees), -1 otherwise
  explicit Tree(int d) : dof(d) {}
  int size() const { return static_cast<int>(parent.size()); }
  const double* at(int i) const { return q.data() + static_cast<size_t>(i) * dof; }
  int add(const double* x, int par, int goal) {
    q.insert(q.end(), x, x + dof);
    parent.push_back(par);
    root_goal.push_back(goal);
    return size() - 1;
  }
  int nearest(const double* x, const std::vector<int>& active) const {
    int best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (int i = 0; i < size(); ++i) {
      const double* p = at(i);
      double d = 0;
      for (int j : active) d += (p[j] - x[j]) * (p[j] - x[j]);
      if (d < best_d) best_d = d, best = i;
    }
    return best;
  }
};

enum class Extend { trapped, advanced, reached };

bool within_limits(const core::Robot& robot, const double* q) {
  const Eigen::VectorXd& lo = robot.lower_limits();
  const Eigen::VectorXd& hi = robot.upper_limits();
  for (int j = 0; j < robot.dof(); ++j)
    if (!std::isfinite(q[j]) || q[j] < lo[j] - 1e-9 || q[j] > hi[j] + 1e-9) return false;
  return true;
}

// Roots the start tree at `start` and the goal tree at every collision-free goal (inactive joints
// held at the start's values); false (and out.status) when the start collides or no goal is free.
bool root_trees(const geometry::CollisionChecker& checker, const RrtSettings& settings, const Eigen::VectorXd& start,
                const Trajectory& goals, geometry::CollisionWorkspace& ws, Tree& ta, Tree& tb, RrtResult& out) {
  const core::Robot& robot = checker.robot();
  const int dof = robot.dof();
  if (!within_limits(robot, start.data())) throw std::invalid_argument("start: outside the joint limits or not finite");
  ++out.checks;
  if (checker.in_collision(start.data(), ws)) {
    out.status = RrtStatus::invalid_start;
    return false;
  }
  ta.add(start.data(), -1, -1);
  for (int g = 0; g < goals.rows(); ++g) {
    Eigen::VectorXd q = goals.row(g).transpose();
    for (int j = 0; j < dof; ++j)
      if (!(settings.active.empty() || settings.active[j])) q[j] = start[j];
    if (!within_limits(robot, q.data()))
      throw std::invalid_argument("goals row " + std::to_string(g) + ": outside the joint limits");
    ++out.checks;
    if (!checker.in_collision(q.data(), ws)) tb.add(q.data(), -1, g);
  }
  if (tb.size() == 0) {
    out.status = RrtStatus::invalid_goals;
    return false;
  }
  return true;
}

// The solved path: the start tree's branch from its root to node ia, then the goal tree's branch
// from node ib's parent to its goal.
void join_path(const Tree& ta, const Tree& tb, int ia, int ib, RrtResult& out) {
  const int dof = ta.dof;
  std::vector<int> front, back;
  for (int i = ia; i >= 0; i = ta.parent[i]) front.push_back(i);
  for (int i = tb.parent[ib]; i >= 0; i = tb.parent[i]) back.push_back(i);
  std::reverse(front.begin(), front.end());
  out.path.resize(static_cast<long>(front.size() + back.size()), dof);
  long r = 0;
  for (int i : front) out.path.row(r++) = Eigen::Map<const Eigen::RowVectorXd>(ta.at(i), dof);
  for (int i : back) out.path.row(r++) = Eigen::Map<const Eigen::RowVectorXd>(tb.at(i), dof);
  out.goal = tb.root_goal[ib];
  out.status = RrtStatus::solved;
}

}  // namespace

MotionPlanner::MotionPlanner(const geometry::CollisionChecker& checker, RrtSettings settings)
    : checker_(checker), settings_(std::move(settings)), bound_(checker) {
  const int dof = checker.robot().dof();
  if (!settings_.active.empty() && static_cast<int>(settings_.active.size()) != dof)
    throw std::invalid_argument("active: expected " + std::to_string(dof) + " flags, got " +
                                std::to_string(settings_.active.size()));
  for (int j = 0; j < dof; ++j)
    if (settings_.active.empty() || settings_.active[j]) active_.push_back(j);
  if (!(settings_.range > 0) || !(settings_.resolution > 0) || !std::isfinite(settings_.range) ||
      !std::isfinite(settings_.resolution))
    throw std::invalid_argument("range and resolution must be finite and > 0");
  if (!(settings_.goal_bias >= 0 && settings_.goal_bias <= 1))
    throw std::invalid_argument("goal_bias: expected a fraction in [0, 1]");
}

bool MotionPlanner::motion_certified(const double* a, const double* b, geometry::CollisionWorkspace& ws,
                                     long* checks) const {
  constexpr double kMinClearance = 1e-5;  // m: closer is no proof (and would take ever smaller steps)
  constexpr int kMaxChecks = 20000;
  const int dof = checker_.robot().dof();
  const double total = bound_.bound(a, b);
  if (!(total > 0.0)) return true;  // a == b: no motion (a itself is not checked)
  Eigen::VectorXd x(dof);
  // Intervals of t not yet proved free, widest first (a FIFO of halves): the midpoint's clearance d
  // proves [t - d/total, t + d/total] free, since no robot point moves farther than d within it. The
  // midpoints come coarse to fine, so an obstacle crossed midway is met after a few queries (as a
  // sampled check meets it), and each query proves both sides of its state, not only the one ahead.
  std::deque<std::pair<double, double>> open{{0.0, 1.0}};
  for (int n = 0; !open.empty(); ++n) {
    if (n == kMaxChecks) return false;
    const auto [lo, hi] = open.front();
    open.pop_front();
    const double t = 0.5 * (lo + hi);
    for (int j = 0; j < dof; ++j) x[j] = a[j] + t * (b[j] - a[j]);
    if (checks) ++*checks;
    // A clearance proving the whole interval is all it needs to know.
    const double d = checker_.min_distance(x.data(), ws, kMinClearance + 0.5 * (hi - lo) * total * (1.0 + 1e-9));
    if (!(d > kMinClearance)) return false;
    // Proved: clearance above kMinClearance on the whole segment, so any piece of it proves again.
    const double r = (d - kMinClearance) / total;
    if (t - r > lo) open.emplace_back(lo, t - r);
    if (t + r < hi) open.emplace_back(t + r, hi);
  }
  return true;
}

bool MotionPlanner::motion_valid(const double* a, const double* b, geometry::CollisionWorkspace& ws,
                                 long* checks) const {
  if (settings_.certified) {
    if (checks) ++*checks;
    if (checker_.in_collision(b, ws)) return false;  // the end first: most rejected edges end in an obstacle
    return motion_certified(a, b, ws, checks);
  }
  const int n = bound_.steps(a, b, settings_.resolution);
  const int dof = checker_.robot().dof();
  Eigen::VectorXd x(dof);
  auto check = [&](int k) {
    const double t = static_cast<double>(k) / n;
    for (int j = 0; j < dof; ++j) x[j] = a[j] + t * (b[j] - a[j]);
    if (checks) ++*checks;
    return !checker_.in_collision(x.data(), ws);
  };
  if (!check(n)) return false;  // the end first: most rejected edges end in an obstacle
  // Then coarse to fine (strides of halving powers of two), which finds a wall crossed midway soonest.
  int stride = 1;
  while (stride * 2 < n) stride *= 2;
  std::vector<char> seen(static_cast<size_t>(n), 0);
  for (; stride >= 1; stride /= 2)
    for (int k = stride; k < n; k += stride) {
      if (seen[k]) continue;
      seen[k] = 1;
      if (!check(k)) return false;
    }
  return true;
}

RrtResult MotionPlanner::rrt_connect(const Eigen::VectorXd& start, const Trajectory& goals) const {
  const auto t0 = Clock::now();
  const core::Robot& robot = checker_.robot();
  const int dof = robot.dof();
  core::require_size("start", dof, start.size(), "joint values");
  if (goals.rows() < 1) throw std::invalid_argument("goals: expected at least one goal configuration");
  core::require_size("goals columns", dof, goals.cols(), "joint values");
  const Eigen::VectorXd& lo = robot.lower_limits();
  const Eigen::VectorXd& hi = robot.upper_limits();
  RrtResult out;
  geometry::CollisionWorkspace ws(checker_);
  Tree ta(dof), tb(dof);
  if (!root_trees(checker_, settings_, start, goals, ws, ta, tb, out)) return out;
  std::mt19937_64 rng(settings_.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Eigen::VectorXd sample = start, step(dof);
  // Extend tree t towards x by at most `range`; the new node's index in `*added`.
  auto extend = [&](Tree& t, const double* x, int* added) {
    const int near = t.nearest(x, active_);
    const double* qn = t.at(near);
    double d2 = 0;
    for (int j : active_) d2 += (x[j] - qn[j]) * (x[j] - qn[j]);
    const double d = std::sqrt(d2);
    const bool reach = d <= settings_.range;
    for (int j = 0; j < dof; ++j) step[j] = reach ? x[j] : qn[j] + (x[j] - qn[j]) * settings_.range / d;
    if (d == 0.0) {
      *added = near;
      return Extend::reached;
    }
    if (!motion_valid(qn, step.data(), ws, &out.checks)) return Extend::trapped;
    *added = t.add(step.data(), near, t.root_goal[near]);
    return reach ? Extend::reached : Extend::advanced;
  };
  Tree* a = &ta;
  Tree* b = &tb;
  for (out.iterations = 0; out.iterations < settings_.max_iterations; ++out.iterations) {
    if ((out.iterations & 31) == 0 && std::chrono::duration<double>(Clock::now() - t0).count() > settings_.time_limit) {
      out.status = RrtStatus::timeout;
      break;
    }
    if (a == &ta && unit(rng) < settings_.goal_bias) {
      sample = tb.size() ? Eigen::Map<const Eigen::VectorXd>(
                               tb.at(std::uniform_int_distribution<int>(0, tb.size() - 1)(rng)), dof)
                         : sample;
    } else {
      for (int j : active_) sample[j] = lo[j] + unit(rng) * (hi[j] - lo[j]);
    }
    int na = -1;
    if (extend(*a, sample.data(), &na) != Extend::trapped) {
      const Eigen::VectorXd target = Eigen::Map<const Eigen::VectorXd>(a->at(na), dof);
      int nb = -1;
      Extend e;
      do e = extend(*b, target.data(), &nb);
      while (e == Extend::advanced);
      if (e == Extend::reached) {
        // Join: the start tree's branch to its root, then the goal tree's branch to its goal.
        join_path(ta, tb, a == &ta ? na : nb, a == &ta ? nb : na, out);
        ++out.iterations;
        break;
      }
    }
    std::swap(a, b);
  }
  if (out.status != RrtStatus::solved && out.iterations >= settings_.max_iterations) out.status = RrtStatus::iterations;
  out.nodes = ta.size() + tb.size();
  out.seconds = std::chrono::duration<double>(Clock::now() - t0).count();
  return out;
}

Trajectory MotionPlanner::shortcut(const Trajectory& path, int attempts, std::uint64_t seed, double min_gain) const {
  if (path.rows() < 3) return path;
  const int dof = static_cast<int>(path.cols());
  geometry::CollisionWorkspace ws(checker_);
  std::vector<Eigen::RowVectorXd> pts;
  for (long i = 0; i < path.rows(); ++i) pts.push_back(path.row(i));
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  // A point at fraction t of segment i.
  auto point = [&](int i, double t) -> Eigen::RowVectorXd { return (1 - t) * pts[i] + t * pts[i + 1]; };
  std::vector<double> seg;  // segment lengths of pts
  auto measure = [&] {
    seg.resize(pts.size() - 1);
    for (size_t s = 0; s + 1 < pts.size(); ++s) seg[s] = (pts[s + 1] - pts[s]).norm();
  };
  measure();
  for (int k = 0; k < attempts && pts.size() >= 3; ++k) {
    const int segs = static_cast<int>(pts.size()) - 1;
    std::uniform_int_distribution<int> pick(0, segs - 1);
    int i = pick(rng), j = pick(rng);
    if (i == j) continue;
    if (i > j) std::swap(i, j);
    const double ti = unit(rng), tj = unit(rng);
    const Eigen::RowVectorXd a = point(i, ti), b = point(j, tj);
    // The motion check is the cost: not paid for a shortcut that would gain next to nothing.
    double along = (1 - ti) * seg[i] + tj * seg[j], length = 0.0;
    for (int s = i + 1; s < j; ++s) along += seg[s];
    for (double l : seg) length += l;
    if (along - (b - a).norm() < min_gain * length) continue;
    if (!motion_valid(a.data(), b.data(), ws)) continue;
    // The new segment a -> b stands for everything between (the checked states lie on it).
    std::vector<Eigen::RowVectorXd> next(pts.begin(), pts.begin() + i + 1);
    next.push_back(a);
    next.push_back(b);
    next.insert(next.end(), pts.begin() + j + 1, pts.end());
    pts.swap(next);
    measure();
  }
  // Drop vertices a straight segment can skip (greedy, from the start), and repeated points.
  std::vector<Eigen::RowVectorXd> kept{pts.front()};
  size_t i = 0;
  while (i + 1 < pts.size()) {
    size_t far = i + 1;
    for (size_t j = pts.size() - 1; j > i + 1; --j)
      if (motion_valid(pts[i].data(), pts[j].data(), ws)) {
        far = j;
        break;
      }
    if ((pts[far] - kept.back()).norm() > 0) kept.push_back(pts[far]);
    i = far;
  }
  Trajectory out(static_cast<long>(kept.size()), dof);
  for (size_t r = 0; r < kept.size(); ++r) out.row(static_cast<long>(r)) = kept[r];
  return out;
}

int MotionPlanner::first_invalid_segment(const Trajectory& path) const {
  geometry::CollisionWorkspace ws(checker_);
  if (path.rows() && checker_.in_collision(path.row(0).data(), ws)) return 0;
  // The waypoints first (one cheap query each): a path that fails mostly fails at one, and then only
  // the segments before it need proving.
  long end = path.rows();
  for (long i = 1; i < path.rows(); ++i) {
    const Eigen::RowVectorXd q = path.row(i);
    if (checker_.in_collision(q.data(), ws)) {
      end = i;
      break;
    }
  }
  for (long i = 0; i + 1 < end; ++i) {
    const Eigen::RowVectorXd a = path.row(i), b = path.row(i + 1);
    // b is known free (the pass above): the certified check need not query it again
    const bool ok =
        settings_.certified ? motion_certified(a.data(), b.data(), ws) : motion_valid(a.data(), b.data(), ws);
    if (!ok) return static_cast<int>(i);
  }
  return end < path.rows() ? static_cast<int>(end - 1) : -1;
}

}  // namespace pickplan::omg
