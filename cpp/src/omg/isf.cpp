#include "pickplan/omg/isf.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "pickplan/core/errors.hpp"
#include "pickplan/geometry/point_index.hpp"

namespace pickplan::omg {

// The tree owns the points it refers to: refiners placed elsewhere share it (with_object).
struct GraspRefiner::Index {
  geometry::Vertices source;
  geometry::PointIndex points;
  explicit Index(const geometry::Vertices& pts) : source(pts), points(&source) {}
};

GraspRefiner::~GraspRefiner() = default;

GraspRefiner::GraspRefiner(std::shared_ptr<const core::Robot> robot, int hand_link, geometry::Vertices contacts,
                           geometry::Vertices contact_normals, std::shared_ptr<const geometry::SceneSdf> hand_sdf,
                           geometry::Vertices object_points, geometry::Vertices object_normals,
                           std::shared_ptr<const geometry::SceneSdf> scene, BodyPoints body, std::uint64_t exclude_mask,
                           IsfSettings settings)
    : robot_(std::move(robot)),
      hand_(hand_link),
      contacts_(std::move(contacts)),
      contact_normals_(std::move(contact_normals)),
      hand_sdf_(std::move(hand_sdf)),
      object_points_(std::move(object_points)),
      object_normals_(std::move(object_normals)),
      scene_(std::move(scene)),
      body_(std::move(body)),
      exclude_mask_(exclude_mask),
      settings_(std::move(settings)) {
  if (!robot_ || !hand_sdf_ || !scene_) throw std::invalid_argument("ISF: robot, hand SDF and scene must not be null");
  if (hand_ < 0 || hand_ >= robot_->num_links()) throw std::invalid_argument("ISF: hand link out of range");
  if (contacts_.rows() == 0) throw std::invalid_argument("ISF: no hand contact points");
  core::require_size("ISF contact normals", contacts_.rows(), contact_normals_.rows(), "rows");
  core::require_finite("ISF contact points", contacts_.data(), contacts_.size());
  core::require_finite("ISF contact normals", contact_normals_.data(), contact_normals_.size());
  if (object_points_.rows() == 0) throw std::invalid_argument("ISF: no object surface points");
  core::require_size("ISF object normals", object_points_.rows(), object_normals_.rows(), "rows");
  core::require_finite("ISF object points", object_points_.data(), object_points_.size());
  core::require_finite("ISF object normals", object_normals_.data(), object_normals_.size());
  core::require_size("ISF body points: links", body_.points.rows(), static_cast<long>(body_.link.size()), "entries");
  for (int l : body_.link)
    if (l < 0 || l >= robot_->num_links())
      throw std::invalid_argument("ISF body points: link index " + std::to_string(l) + " out of range [0, " +
                                  std::to_string(robot_->num_links()) + ")");
  core::require_finite("ISF body points", body_.points.data(), body_.points.size());
  if (!settings_.active.empty())
    core::require_size("ISF settings: active joint mask", robot_->dof(), static_cast<long>(settings_.active.size()),
                       "entries");
  index_ = std::make_shared<const Index>(object_points_);
}

std::shared_ptr<GraspRefiner> GraspRefiner::with_object(geometry::Vertices object_points,
                                                        geometry::Vertices object_normals,
                                                        const core::Transform& motion) const {
  core::require_rigid("ISF: object motion", motion.matrix());
  core::require_size("ISF object points", object_points_.rows(), object_points.rows(),
                     "rows (the same samples, moved)");
  core::require_size("ISF object normals", object_points.rows(), object_normals.rows(), "rows");
  core::require_finite("ISF object points", object_points.data(), object_points.size());
  core::require_finite("ISF object normals", object_normals.data(), object_normals.size());
  const Eigen::Index n = object_points.rows();
  for (const Eigen::Index k : {Eigen::Index{0}, n / 2, n - 1}) {  // the motion must be the points' own
    const Eigen::Vector3d moved = motion.apply(object_points_.row(k).transpose());
    if ((moved - object_points.row(k).transpose()).norm() > 1e-9 * (1.0 + moved.norm()))
      throw std::invalid_argument(
          "ISF with_object: the motion does not take the object points onto the new ones (row " + std::to_string(k) +
          ")");
  }
  // A copy of this refiner (no validation, no tree built) with the new samples.
  std::shared_ptr<GraspRefiner> out(new GraspRefiner(*this));
  out->object_points_ = std::move(object_points);
  out->object_normals_ = std::move(object_normals);
  out->tree_from_world_ = tree_from_world_ * motion.inverse();
  return out;
}

// Nearest object point of every contact; a repeated neighbour keeps only its closest contact.
// Adds f_pml and f_align (eqs. 11-12) and their force and torque on the hand.
void GraspRefiner::contact_terms(const core::Transform& H, GraspTerms& t, Eigen::Vector3d& F,
                                 Eigen::Vector3d& tau) const {
  const IsfSettings& s = settings_;
  const double unit = s.length_unit;
  const int M = static_cast<int>(contacts_.rows());
  std::vector<size_t> nn(M);
  std::vector<double> dist2(M);
  std::vector<Eigen::Vector3d> uh(M), un(M);
  for (int j = 0; j < M; ++j) {
    uh[j] = H.apply(contacts_.row(j).transpose());
    un[j] = H.R * contact_normals_.row(j).transpose();
    const Eigen::Vector3d in_tree = tree_from_world_.apply(uh[j]);
    index_->points.nearest(in_tree.data(), &nn[j], &dist2[j]);
    dist2[j] = (uh[j] - object_points_.row(nn[j]).transpose()).squaredNorm();  // in the world, as before a move
  }
  for (int j = 0; j < M; ++j) {
    bool keep = true;
    for (int k = 0; k < M && keep; ++k)
      if (k != j && nn[k] == nn[j] && (dist2[k] < dist2[j] || (dist2[k] == dist2[j] && k < j))) keep = false;
    if (!keep) continue;
    ++t.matched;
    const Eigen::Vector3d uo = object_points_.row(nn[j]).transpose();
    const Eigen::Vector3d no = object_normals_.row(nn[j]).transpose();
    const double r = (uh[j] - uo).dot(no) / unit;  // eq. 11 residual, in length units
    const double a = un[j].dot(no) + 1.0;          // eq. 12 residual
    t.pml += r * r;
    t.align += a * a;
    const Eigen::Vector3d gp = 2.0 * r / unit * no;     // d f_pml / d u_h
    const Eigen::Vector3d gn = 2.0 * s.alpha * a * no;  // d (alpha f_align) / d u_h^n
    F += gp;
    tau += (uh[j] - H.p).cross(gp) + un[j].cross(gn);
  }
}

// Hand collision: object points inside (or near) the hand push the hand away (eq. 14).
void GraspRefiner::hand_collision_terms(const core::Transform& H, GraspTerms& t, Eigen::Vector3d& F,
                                        Eigen::Vector3d& tau) const {
  const IsfSettings& s = settings_;
  const double unit = s.length_unit;
  const core::Transform Hinv = H.inverse();
  Eigen::Vector3d g;
  for (Eigen::Index k = 0; k < object_points_.rows(); ++k) {
    const Eigen::Vector3d o = object_points_.row(k).transpose();
    const double d = hand_sdf_->distance(Hinv.apply(o), &g, s.hand_epsilon, 0);
    if (d >= s.hand_epsilon) continue;
    double dc;
    t.hand += chomp_cost(d, s.hand_epsilon, &dc) / unit;
    const Eigen::Vector3d gw = -(dc / unit) * (H.R * g);  // moving the hand toward o raises the cost
    F += s.gamma * gw;
    tau += s.gamma * (o - H.p).cross(gw);
  }
}

// Arm obstacle cost at the single configuration g (eq. 14's f_obstacle).
void GraspRefiner::arm_obstacle_terms(const core::RobotWorkspace& ws, GraspTerms& t, Eigen::VectorXd* gq) const {
  const IsfSettings& s = settings_;
  Eigen::Vector3d g;
  Eigen::Matrix<double, 3, Eigen::Dynamic> Jp(3, robot_->dof());
  for (int u = 0; u < body_.size(); ++u) {
    const Eigen::Vector3d x = ws.link_pose[body_.link[u]].apply(body_.points.row(u).transpose());
    const double d = scene_->distance(x, &g, s.arm_epsilon, exclude_mask_);
    if (d >= s.arm_epsilon) continue;
    double dc;
    t.obstacle += chomp_cost(d, s.arm_epsilon, &dc);
    if (gq) {
      robot_->position_jacobian_world(ws, body_.link[u], x, Jp);
      *gq += s.gamma * s.beta * Jp.transpose() * (dc * g);
    }
  }
}

GraspTerms GraspRefiner::cost(const Eigen::VectorXd& q, Eigen::VectorXd* grad) const {
  robot_->check_configuration(q.data(), q.size());
  const IsfSettings& s = settings_;
  core::RobotWorkspace ws(*robot_);
  robot_->forward_kinematics(q.data(), ws);
  const core::Transform& H = ws.link_pose[hand_];
  GraspTerms t;
  // Wrench on the hand about its origin: force (d f / d position) and torque.
  Eigen::Vector3d F = Eigen::Vector3d::Zero(), tau = Eigen::Vector3d::Zero();
  contact_terms(H, t, F, tau);
  t.isf = t.pml + s.alpha * t.align;
  hand_collision_terms(H, t, F, tau);
  Eigen::VectorXd gq = Eigen::VectorXd::Zero(robot_->dof());
  arm_obstacle_terms(ws, t, grad ? &gq : nullptr);
  t.collision = t.hand + s.beta * t.obstacle;
  t.total = t.isf + s.gamma * t.collision;
  if (grad) {
    Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, robot_->dof());
    robot_->point_jacobian(ws, hand_, Eigen::Vector3d::Zero(), J);
    Eigen::Matrix<double, 6, 1> W;
    W << F, tau;
    gq += J.transpose() * W;
    if (!s.active.empty())
      for (int j = 0; j < robot_->dof(); ++j)
        if (!s.active[j]) gq[j] = 0;
    *grad = gq;
  }
  return t;
}

Eigen::VectorXd GraspRefiner::step(const Eigen::VectorXd& q, GraspTerms* terms) const {
  Eigen::VectorXd grad;
  const GraspTerms t0 = cost(q, &grad);
  // eta_grasp step, capped at max_joint_step, then shortened until f_grasp decreases: each
  // retry goes to the minimizer of the quadratic through f(0), f'(0) and the failed trial,
  // kept within [0.1, 0.5] of the failed length (so at least a halving, as plain backtracking,
  // but a badly scaled first trial costs two or three evaluations instead of eight).
  Eigen::VectorXd dq = -settings_.step_size * grad;
  const double m = dq.cwiseAbs().maxCoeff();
  if (m > settings_.max_joint_step) dq *= settings_.max_joint_step / m;
  const double slope = grad.dot(dq);
  // a step may let the fingers touch the support, or keep them as deep as they were, not press deeper
  const double allowed_depth = std::max(0.0, support_depth(q)) + 1e-9;
  double alpha = 1.0;
  for (int h = 0; h <= settings_.max_halvings; ++h) {
    const Eigen::VectorXd q1 = (q + alpha * dq).cwiseMax(robot_->lower_limits()).cwiseMin(robot_->upper_limits());
    const GraspTerms t1 = cost(q1, nullptr);
    if (t1.total < t0.total && support_depth(q1) <= allowed_depth) {
      if (terms) *terms = t1;
      return q1;
    }
    const double curvature = (t1.total - t0.total - slope * alpha) / (alpha * alpha);
    const double next = curvature > 0 && slope < 0 ? -slope / (2 * curvature) : 0.5 * alpha;
    alpha = std::clamp(next, 0.1 * alpha, 0.5 * alpha);
  }
  if (terms) *terms = t0;
  return q;  // no decrease found: a (local) minimum at this resolution
}

void GraspRefiner::set_support(SupportPlane support) {
  if (support.finger_vertices.rows() > 0) {
    if (!support.finger_vertices.allFinite() || !support.normal.allFinite() || !std::isfinite(support.offset))
      throw std::invalid_argument("support plane: expected finite finger vertices, normal and offset");
    const double n = support.normal.norm();
    if (std::abs(n - 1.0) > 1e-6)
      throw std::invalid_argument("support plane: the normal must be a unit vector, its norm is " + std::to_string(n));
  }
  support_ = std::move(support);
}

double GraspRefiner::support_depth(const Eigen::VectorXd& q) const {
  if (support_.finger_vertices.rows() == 0) return -std::numeric_limits<double>::infinity();
  core::RobotWorkspace ws(*robot_);
  robot_->forward_kinematics(q.data(), ws);
  const core::Transform& hand = ws.link_pose[hand_];
  double lowest = std::numeric_limits<double>::infinity();
  for (int i = 0; i < support_.finger_vertices.rows(); ++i) {
    const Eigen::Vector3d x = hand.apply(support_.finger_vertices.row(i).transpose());
    lowest = std::min(lowest, support_.normal.dot(x) - support_.offset);
  }
  return -lowest;
}

Eigen::VectorXd GraspRefiner::refine(const Eigen::VectorXd& q, int iterations, GraspTerms* terms) const {
  Eigen::VectorXd cur = q;
  GraspTerms t;
  if (iterations <= 0 && terms) t = cost(q, nullptr);  // every step reports its own terms
  for (int i = 0; i < iterations; ++i) cur = step(cur, &t);
  if (terms) *terms = t;
  return cur;
}

}  // namespace pickplan::omg
