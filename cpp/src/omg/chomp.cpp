#include "pickplan/omg/chomp.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include <Eigen/Cholesky>

#include "pickplan/core/errors.hpp"

namespace pickplan::omg {

namespace {
constexpr int kMaxPrecomputedTail = 16;

// Sizes only (O(1), so hot loops can afford it): xi is (n, dof) and q0 has dof entries.
void require_shapes(const ChompProblem& p, const Trajectory& xi, const Eigen::VectorXd& q0) {
  core::require_size("trajectory rows", p.settings().n, xi.rows(), "waypoints");
  core::require_size("trajectory columns", p.robot().dof(), xi.cols(), "joint values");
  core::require_size("start configuration", p.robot().dof(), q0.size(), "joint values");
}
}  // namespace

ChompWorkspace::ChompWorkspace(const ChompProblem& p)
    : fk(p.settings().n + 1, core::RobotWorkspace(p.robot())),
      x((p.settings().n + 1) * p.body().size(), 3),
      grad_d((p.settings().n + 1) * p.body().size(), 3),
      d((p.settings().n + 1) * p.body().size()),
      term(static_cast<size_t>(p.settings().n) * p.body().size()),
      live(static_cast<size_t>(p.settings().n + 1) * p.groups().size(), 1),
      wrench(
          Eigen::Matrix<double, Eigen::Dynamic, 6, Eigen::RowMajor>::Zero((p.settings().n + 1) * p.groups().size(), 6)),
      grad(p.settings().n, p.robot().dof()),
      u(p.settings().n, p.robot().dof()) {
  order.reserve(term.size());
}

ChompProblem::ChompProblem(std::shared_ptr<const core::Robot> robot, std::shared_ptr<const geometry::SceneSdf> scene,
                           BodyPoints body, ChompSettings settings)
    : robot_(std::move(robot)), scene_(std::move(scene)), body_(std::move(body)), settings_(std::move(settings)) {
  if (!robot_ || !scene_) throw std::invalid_argument("CHOMP: robot and scene must not be null");
  const auto& s = settings_;
  if (s.n < 2) throw std::invalid_argument("CHOMP settings: n must be >= 2, got " + std::to_string(s.n));
  if (!(s.duration > 0) || !(s.step_size > 0) || !(s.epsilon > 0) || !(s.lambda >= 0))
    throw std::invalid_argument("CHOMP settings: duration, step_size and epsilon must be > 0 and lambda >= 0");
  if (s.top_k < 0 || s.obstacle_tail < 0 || s.obstacle_tail > s.n)
    throw std::invalid_argument("CHOMP settings: top_k >= 0 and 0 <= obstacle_tail <= n required");
  if (!s.active.empty())
    core::require_size("CHOMP settings: active joint mask", robot_->dof(), static_cast<long>(s.active.size()),
                       "entries");
  core::require_size("body points: links", body_.points.rows(), static_cast<long>(body_.link.size()), "entries");
  for (int l : body_.link)
    if (l < 0 || l >= robot_->num_links())
      throw std::invalid_argument("body points: link index " + std::to_string(l) + " out of range");
  core::require_finite("body points", body_.points.data(), body_.points.size());
  for (int u = 0; u < body_.size(); ++u) {
    if (groups_.empty() || groups_.back().link != body_.link[u]) groups_.push_back({body_.link[u], u, u});
    groups_.back().end = u + 1;
  }
  group_of_.resize(body_.size());
  for (int gi = 0; gi < static_cast<int>(groups_.size()); ++gi)
    for (int u = groups_[gi].begin; u < groups_[gi].end; ++u) group_of_[u] = gi;
  for (LinkGroup& g : groups_) {
    const auto pts = body_.points.middleRows(g.begin, g.end - g.begin);
    g.center = 0.5 * (pts.colwise().minCoeff() + pts.colwise().maxCoeff()).transpose();
    g.radius = (pts.rowwise() - g.center.transpose()).rowwise().norm().maxCoeff();
  }
  dt_ = s.duration / s.n;
  // A = K^T K with K the first-difference matrix scaled by 1/dt: tridiagonal, last diagonal a.
  const double a = 1.0 / (dt_ * dt_);
  chol_diag_.resize(s.n);
  chol_sub_.resize(s.n);
  for (int i = 0; i < s.n; ++i) {
    const double diag = (i == s.n - 1) ? a : 2 * a;
    chol_sub_[i] = i == 0 ? 0.0 : -a / chol_diag_[i - 1];
    chol_diag_[i] = std::sqrt(diag - chol_sub_[i] * chol_sub_[i]);
  }
  const int max_m = std::min(s.n, kMaxPrecomputedTail);
  for (int m = 1; m <= max_m; ++m) {
    Trajectory E = Trajectory::Zero(s.n, m), X(s.n, m);
    for (int j = 0; j < m; ++j) E(s.n - m + j, j) = 1.0;
    solve_A(E, X);
    const Eigen::MatrixXd S = X.bottomRows(m);
    projectors_.push_back(X * S.inverse());
  }
}

void ChompProblem::solve_A(const Trajectory& v, Trajectory& out) const {
  const int n = settings_.n;
  core::require_size("solve_A: v", n, v.rows(), "rows");
  out.resize(v.rows(), v.cols());
  out.row(0) = v.row(0) / chol_diag_[0];
  for (int i = 1; i < n; ++i) out.row(i) = (v.row(i) - chol_sub_[i] * out.row(i - 1)) / chol_diag_[i];
  out.row(n - 1) /= chol_diag_[n - 1];
  for (int i = n - 2; i >= 0; --i) out.row(i) = (out.row(i) - chol_sub_[i + 1] * out.row(i + 1)) / chol_diag_[i];
}

Eigen::MatrixXd ChompProblem::A_matrix() const {
  const int n = settings_.n;
  const double a = 1.0 / (dt_ * dt_);
  Eigen::MatrixXd A = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) {
    A(i, i) = i == n - 1 ? a : 2 * a;
    if (i > 0) A(i, i - 1) = A(i - 1, i) = -a;
  }
  return A;
}

const Eigen::MatrixXd& ChompProblem::projector(int m) const {
  if (m < 1 || m > static_cast<int>(projectors_.size()))
    throw std::invalid_argument("CHOMP goal: expected 1 to " + std::to_string(projectors_.size()) + " goal rows, got " +
                                std::to_string(m));
  return projectors_[m - 1];
}

void ChompProblem::check_trajectory(const Trajectory& xi, const Eigen::VectorXd& q0) const {
  if (xi.rows() != settings_.n || xi.cols() != robot_->dof()) {
    std::ostringstream msg;
    msg << "trajectory: expected shape (" << settings_.n << ", " << robot_->dof() << "), got (" << xi.rows() << ", "
        << xi.cols() << ")";
    throw std::invalid_argument(msg.str());
  }
  core::require_finite("trajectory", xi.data(), xi.size());
  robot_->check_configuration(q0.data(), q0.size());
}

void ChompProblem::mask_inactive(Trajectory& g) const {
  if (settings_.active.empty()) return;
  for (int j = 0; j < robot_->dof(); ++j)
    if (!settings_.active[j]) g.col(j).setZero();
}

double ChompProblem::prior(const Trajectory& xi, const Eigen::VectorXd& q0, Trajectory* grad) const {
  require_shapes(*this, xi, q0);
  const int n = settings_.n;
  const double inv_dt2 = 1.0 / (dt_ * dt_);
  double f = 0;
  if (grad) grad->setZero(n, robot_->dof());
  for (int t = 0; t < n; ++t) {
    const Eigen::RowVectorXd diff =
        t == 0 ? Eigen::RowVectorXd(xi.row(0) - q0.transpose()) : Eigen::RowVectorXd(xi.row(t) - xi.row(t - 1));
    f += 0.5 * diff.squaredNorm() * inv_dt2;
    if (grad) {
      grad->row(t) += diff * inv_dt2;
      if (t > 0) grad->row(t - 1) -= diff * inv_dt2;
    }
  }
  return f;
}

ChompProblem::GroupReach ChompProblem::group_reach(const core::RobotWorkspace& fk, const LinkGroup& group) const {
  if (!settings_.link_culling) return {true, true};
  const Eigen::Vector3d c = fk.link_pose[group.link].apply(group.center);
  const geometry::SceneSdf::PartBounds b = scene_->part_lower_bounds(c, settings_.exclude_mask);
  return {b.objects - group.radius < settings_.epsilon, b.table - group.radius < settings_.epsilon};
}

void ChompProblem::transform_points(const core::RobotWorkspace& fk, const LinkGroup& group, double* x) const {
  const core::Transform& T = fk.link_pose[group.link];
  const double* p = body_.points.data() + 3 * static_cast<long>(group.begin);
  for (int u = group.begin; u < group.end; ++u, p += 3, x += 3) {
    Eigen::Map<Eigen::Vector3d> xw(x);
    xw.noalias() = T.R * Eigen::Map<const Eigen::Vector3d>(p) + T.p;
  }
}

// ws.live per (waypoint, group): 1 = points and distances evaluated, 2 = points only, 0 = neither.
// The start has no term and waypoints past last_t are not charged, so neither needs distances
// (the start's points are made on demand in obstacle_terms, for the speed of waypoint 1).
void ChompProblem::obstacle_distances(const Trajectory& xi, const Eigen::VectorXd& q0, int last_t,
                                      ChompWorkspace& ws) const {
  const int N = body_.size(), G = static_cast<int>(groups_.size());
  const double eps = settings_.epsilon;
  for (int t = 0; t <= last_t; ++t) {
    robot_->forward_kinematics(t == 0 ? q0.data() : xi.row(t - 1).data(), ws.fk[t]);
    for (int gi = 0; gi < G; ++gi) {
      char& live = ws.live[t * G + gi];
      live = 0;
      if (t == 0) continue;
      const LinkGroup& grp = groups_[gi];
      const GroupReach reach = group_reach(ws.fk[t], grp);
      if (!reach.any()) continue;
      live = 1;
      const long first = static_cast<long>(t) * N + grp.begin, count = grp.end - grp.begin;
      transform_points(ws.fk[t], grp, ws.x.data() + 3 * first);
      scene_->distances(ws.x.data() + 3 * first, count, ws.d.data() + first, ws.grad_d.data() + 3 * first, eps,
                        settings_.exclude_mask, reach.objects, reach.table);
    }
  }
}

// Each near point's term: cost times its speed; colliding points counted.
void ChompProblem::obstacle_terms(int last_t, ChompWorkspace& ws, ObjectiveTerms& out) const {
  const int N = body_.size(), G = static_cast<int>(groups_.size());
  const double eps = settings_.epsilon;
  ws.order.clear();
  const double inv_dt = 1.0 / dt_;
  // ws.term is only read at the indices ws.order lists, all written below: no clearing needed.
  for (int t = 1; t <= last_t; ++t)
    for (int gi = 0; gi < G; ++gi) {
      if (ws.live[t * G + gi] != 1) continue;
      const LinkGroup& grp = groups_[gi];
      // The previous waypoint's points are needed for the speed even where they were culled.
      if (!ws.live[(t - 1) * G + gi]) {
        transform_points(ws.fk[t - 1], grp, ws.x.data() + 3 * (static_cast<long>(t - 1) * N + grp.begin));
        ws.live[(t - 1) * G + gi] = 2;
      }
      for (int u = grp.begin; u < grp.end; ++u) {
        const double d = ws.d[t * N + u];
        if (d >= eps) continue;
        if (d < 0) ++out.colliding_points;
        const int i = (t - 1) * N + u;
        const double* xt = ws.x.data() + 3 * (static_cast<long>(t) * N + u);
        const double* xp = xt - 3 * static_cast<long>(N);
        const double speed = std::sqrt((xt[0] - xp[0]) * (xt[0] - xp[0]) + (xt[1] - xp[1]) * (xt[1] - xp[1]) +
                                       (xt[2] - xp[2]) * (xt[2] - xp[2]));
        ws.term[i] = chomp_cost(d, eps, nullptr) * speed * inv_dt;
        if (ws.term[i] > 0) ws.order.push_back(i);
      }
    }
  const int k = settings_.top_k;
  if (k > 0 && static_cast<int>(ws.order.size()) > k) {
    std::nth_element(ws.order.begin(), ws.order.begin() + k, ws.order.end(),
                     [&](int a, int b) { return ws.term[a] != ws.term[b] ? ws.term[a] > ws.term[b] : a < b; });
    ws.order.resize(k);
  }
  for (int i : ws.order) out.obstacle += ws.term[i];
}

// Each term's point forces are summed into a wrench per (waypoint, link group); one chain walk per
// loaded wrench then pulls them all back (J^T f without forming J).
void ChompProblem::obstacle_gradient(ChompWorkspace& ws, Trajectory& g) const {
  const int N = body_.size(), G = static_cast<int>(groups_.size());
  const double eps = settings_.epsilon, inv_dt = 1.0 / dt_;
  const auto load = [&](int t, int u, const Eigen::Vector3d& x, const Eigen::Vector3d& f) {
    const int row = t * G + group_of_[u];
    auto w = ws.wrench.row(row);
    if (w.squaredNorm() == 0) ws.loaded.push_back(row);
    w.head<3>() += f.transpose();
    w.tail<3>() += x.cross(f).transpose();
  };
  ws.loaded.clear();
  for (int i : ws.order) {
    const int t = i / N + 1, u = i % N;
    const double d = ws.d[t * N + u];
    double dc;
    const double c = chomp_cost(d, eps, &dc);
    const Eigen::Vector3d xt = ws.x.row(t * N + u).transpose(), xp = ws.x.row((t - 1) * N + u).transpose();
    const Eigen::Vector3d delta = xt - xp;
    const double len = delta.norm();
    if (len < 1e-12) continue;
    const Eigen::Vector3d dir = delta / len;
    // d/dx_t of c(d(x_t)) |x_t - x_{t-1}| / dt, and the matching term of x_{t-1}.
    load(t, u, xt, (dc * len * ws.grad_d.row(t * N + u).transpose() + c * dir) * inv_dt);
    if (t >= 2) load(t - 1, u, xp, -c * inv_dt * dir);
  }
  for (int row : ws.loaded) {
    const int t = row / G;
    auto w = ws.wrench.row(row);
    robot_->add_wrench_jacobian_transpose(ws.fk[t], groups_[row % G].link, w.head<3>().transpose(),
                                          w.tail<3>().transpose(), g.row(t - 1).data());
    w.setZero();
  }
}

ObjectiveTerms ChompProblem::obstacle(const Trajectory& xi, const Eigen::VectorXd& q0, Trajectory* grad,
                                      ChompWorkspace& ws) const {
  require_shapes(*this, xi, q0);
  if (grad) {
    core::require_size("obstacle gradient rows", settings_.n, grad->rows(), "waypoints");
    core::require_size("obstacle gradient columns", robot_->dof(), grad->cols(), "joint values");
  }
  ObjectiveTerms out;
  const int last_t = settings_.n - settings_.obstacle_tail;
  obstacle_distances(xi, q0, last_t, ws);
  obstacle_terms(last_t, ws, out);
  if (!grad) return out;
  Trajectory& g = ws.u;  // reuse as the obstacle-gradient accumulator
  g.setZero(settings_.n, robot_->dof());
  obstacle_gradient(ws, g);
  if (settings_.clip_gradient > 0) g = g.cwiseMax(-settings_.clip_gradient).cwiseMin(settings_.clip_gradient);
  *grad += g;
  return out;
}

ObjectiveTerms ChompProblem::objective(const Trajectory& xi, const Eigen::VectorXd& q0, int iteration, Trajectory* grad,
                                       ChompWorkspace& ws) const {
  const double lambda = settings_.lambda * std::pow(settings_.lambda_growth, iteration);
  ObjectiveTerms out;
  out.prior = prior(xi, q0, grad);
  if (grad) *grad *= lambda;
  const ObjectiveTerms obs = obstacle(xi, q0, grad, ws);
  out.obstacle = obs.obstacle;
  out.colliding_points = obs.colliding_points;
  out.total = out.obstacle + lambda * out.prior;
  return out;
}

void ChompProblem::project_limits(Trajectory& xi, int m, ChompWorkspace& ws, StepInfo& info) const {
  const Eigen::VectorXd& lo = robot_->lower_limits();
  const Eigen::VectorXd& hi = robot_->upper_limits();
  const Eigen::MatrixXd& M = projector(m);
  Trajectory& v = ws.grad;
  for (int it = 0; it < settings_.joint_limit_steps; ++it) {
    for (int r = 0; r < xi.rows(); ++r)
      for (int c = 0; c < xi.cols(); ++c)
        v(r, c) = xi(r, c) < lo[c] ? lo[c] - xi(r, c) : (xi(r, c) > hi[c] ? hi[c] - xi(r, c) : 0.0);
    v.bottomRows(m).setZero();  // the pinned tail is the goal's business
    mask_inactive(v);
    Eigen::Index r, c;
    const double worst = v.cwiseAbs().maxCoeff(&r, &c);
    if (worst < 1e-9) return;
    // Smooth correction through A^-1, keeping the tail where it is.
    solve_A(v, ws.u);
    ws.u.noalias() -= M * ws.u.bottomRows(m);
    const double scale = std::abs(ws.u(r, c)) > 1e-12 ? worst / std::abs(ws.u(r, c)) : 0.0;
    xi.noalias() += scale * ws.u;
    ++info.limit_projections;
  }
  // Smooth steps left a violation (they fix the worst joint at a time): clamp the rest, so no plan leaves
  // the limits a controller refuses (a shelf plan went 1.5 mrad past panda_joint2 after 10 steps).
  const Eigen::Index free_rows = xi.rows() - m;
  for (Eigen::Index r = 0; r < free_rows; ++r)
    for (Eigen::Index c = 0; c < xi.cols(); ++c)
      if (settings_.active.empty() || settings_.active[c]) xi(r, c) = std::clamp(xi(r, c), lo[c], hi[c]);
}

StepInfo ChompProblem::step(Trajectory& xi, const Eigen::VectorXd& q0, const Trajectory* goal, int iteration,
                            ChompWorkspace& ws) const {
  check_trajectory(xi, q0);
  StepInfo info;
  Trajectory& grad = ws.grad;
  info.before = objective(xi, q0, iteration, &grad, ws);
  mask_inactive(grad);
  solve_A(grad, ws.u);
  const int m = goal ? static_cast<int>(goal->rows()) : 1;
  const Eigen::MatrixXd& M = projector(m);
  const double s = settings_.step_size;
  // eq. 7: unconstrained step, its component that would move the tail removed, then the offset
  // that puts the tail exactly on the goal.
  Trajectory delta = -s * ws.u;
  delta.noalias() += s * (M * ws.u.bottomRows(m));
  if (goal) {
    core::require_size("CHOMP goal", robot_->dof(), goal->cols(), "joint values per row");
    core::require_finite("CHOMP goal", goal->data(), goal->size());
    delta.noalias() -= M * (xi.bottomRows(m) - *goal);
  }
  xi += delta;
  project_limits(xi, m, ws, info);
  info.goal_error = goal ? (xi.bottomRows(m) - *goal).cwiseAbs().maxCoeff() : 0.0;
  return info;
}

ChompResult ChompProblem::optimize(Trajectory xi, const Eigen::VectorXd& q0, const Trajectory& goal,
                                   int iterations) const {
  if (iterations < 0) throw std::invalid_argument("CHOMP: iterations must be >= 0, got " + std::to_string(iterations));
  const auto t0 = std::chrono::steady_clock::now();
  ChompWorkspace ws(*this);
  ChompResult res;
  for (int i = 0; i < iterations; ++i) {
    StepInfo info = step(xi, q0, &goal, i, ws);
    res.objective.push_back(info.before.total);
  }
  res.final_terms = objective(xi, q0, iterations, nullptr, ws);
  res.xi = std::move(xi);
  res.iterations = iterations;
  res.status = ChompStatus::ok;
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return res;
}

}  // namespace pickplan::omg
