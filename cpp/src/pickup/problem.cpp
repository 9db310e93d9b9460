// What a pick-up problem is (Thakar et al., Sec. III and V): the success-probability surface
// rho_sigma(S_g, S_c) as a Bernstein polynomial, the problem's validation, and the polynomial
// degrees of the DOFs. The constraint rows are in nlp_layout.cpp, the Ipopt driver in solve.cpp.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "nlp_detail.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {

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
                                std::to_string(sg_hi) + "], S_c [" + std::to_string(sc_lo) + ", " +
                                std::to_string(sc_hi) + "]");
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
  const double u = std::clamp((sg - sg_lo) / (sg_hi - sg_lo), 0.0, 1.0),
               v = std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0);
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

void PickupProblem::validate(const core::Robot& robot) const {
  const int na = robot.dof() - 3;
  if (na < 1)
    throw std::invalid_argument("robot: expected 3 base DOFs plus an arm, got " + std::to_string(robot.dof()) +
                                " DOFs");
  if (arm_start.size() != na)
    throw std::invalid_argument("arm_start: expected " + std::to_string(na) + " joint values, got " +
                                std::to_string(arm_start.size()));
  if (arm_rate_limits.size() != na)
    throw std::invalid_argument("arm_rate_limits: expected " + std::to_string(na) + " values, got " +
                                std::to_string(arm_rate_limits.size()));
  if ((arm_rate_limits.array() <= 0).any()) throw std::invalid_argument("arm_rate_limits must be positive");
  if (tool_link < 0 || tool_link >= robot.num_links()) throw std::invalid_argument("tool_link: index out of range");
  if (std::abs(approach_dir.norm() - 1.0) > 1e-6) throw std::invalid_argument("approach_dir must be a unit vector");
  if (!(grasp_area_rmax > grasp_area_rmin) || grasp_area_rmin < 0)
    throw std::invalid_argument("grasp area: expected 0 <= rmin < rmax");
  if (!(gamma >= 0 && gamma <= 1))
    throw std::invalid_argument("gamma must lie in [0, 1], got " + std::to_string(gamma));
  if (!(stroke > 0)) throw std::invalid_argument("stroke must be positive");
  if (!(base_speed_limit > 0) || !(base_yaw_rate_limit > 0))
    throw std::invalid_argument("base limits must be positive");
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

namespace detail {
// Sound reachability test of the grasp position: the tool is at most R (sum of the fixed link
// offsets from the first arm joint to the tool, triangle inequality) from the first arm joint, whose
// position is fixed on the base; if even the nearest base pose in the grasping area leaves the grasp
// point farther than R, no trajectory can satisfy the grasp-pose constraint.
bool grasp_unreachable(const core::Robot& robot, const PickupProblem& pb, std::string& why) {
  const int first = robot.link_of_q(3);
  double reach = 0.0;
  for (int k = pb.tool_link; k >= 0 && k != first; k = robot.link(k).parent) {
    if (robot.link(k).joint_type == core::JointType::Prismatic) return false;  // no bound for prismatic arms
    reach += robot.link(k).joint_origin.p.norm();
  }
  core::RobotWorkspace ws(robot);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(robot.dof());
  robot.forward_kinematics(q.data(), ws);
  const Eigen::Vector3d j0 = ws.link_pose[first].p - robot.base().p;
  const double mount = j0.head<2>().norm();
  const double dz = pb.grasp_pose.p.z() - (robot.base().p.z() + j0.z());
  const double dxy_part = (pb.grasp_pose.p.head<2>() - pb.part_xy).norm();
  const double h = std::max(0.0, pb.grasp_area_rmin - mount - dxy_part);
  const double dmin = std::hypot(dz, h);
  if (dmin <= reach) return false;
  why = "grasp point at least " + std::to_string(dmin) + " m from the first arm joint, reach " + std::to_string(reach) +
        " m";
  return true;
}
}  // namespace detail

}  // namespace pickplan::pickup
