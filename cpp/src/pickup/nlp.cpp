// The constraint system of the pick-up NLP (Sec. V-A) with exact first derivatives.
// The DOFs are polynomials P(s) in normalised time s = t / T, so q(t) = P(t / T), q'(t) = P_s / T;
// T1 = s1 T and T2 = s2 T. Each sampled row is a function c(q, q', S_g, S_c) at s = w0 s1 + w1 s2 + c0;
// the chain rule
//   dc/da_ik = c_q[i] B_k(s) + c_q'[i] B'_k(s) / T,  dc/ds = c_q . P_s + c_q' . P_ss / T,
//   dc/dT = -c_q' . q' / T
// turns its partials in (q, q') into the Jacobian in (coefficients, s1, s2, T). Time scaling is then
// one variable (T) instead of a coherent change of every coefficient, which Ipopt handles far better.
#include "pickplan/pickup/nlp.hpp"
#include "nlp_detail.hpp"
#include "pickplan/core/errors.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace pickplan::pickup {
using namespace detail;

namespace detail {
// Tool-point linear/angular velocity Jacobian and the derivatives of (J q') with respect to q.
void velocity_derivatives(const core::Robot& robot, const core::RobotWorkspace& ws, int tool, const Eigen::VectorXd& qd,
                          Eigen::Matrix<double, 6, Eigen::Dynamic>& J, Eigen::Matrix<double, 3, Eigen::Dynamic>& dv,
                          Eigen::Matrix<double, 3, Eigen::Dynamic>& dw) {
  const int n = robot.dof();
  robot.point_jacobian(ws, tool, Eigen::Vector3d::Zero(), J);
  const Eigen::Vector3d p = ws.link_pose[tool].p;
  std::vector<Eigen::Vector3d> a(n), o(n);
  std::vector<char> rev(n), moves_tool(n);
  for (int i = 0; i < n; ++i) {
    const int L = robot.link_of_q(i);
    a[i] = ws.link_pose[L].R * robot.link(L).axis;
    o[i] = ws.link_pose[L].p;
    rev[i] = robot.link(L).joint_type != core::JointType::Prismatic;
    moves_tool[i] = robot.moves(i, tool);
  }
  dv.setZero();
  dw.setZero();
  for (int j = 0; j < n; ++j) {
    if (!moves_tool[j]) continue;
    const Eigen::Vector3d dp = J.block<3, 1>(0, j);
    for (int i = 0; i < n; ++i) {
      if (!moves_tool[i] || qd[i] == 0.0) continue;
      Eigen::Vector3d da = Eigen::Vector3d::Zero(), dor = Eigen::Vector3d::Zero();
      if (j != i && robot.moves(j, robot.link_of_q(i))) {
        if (rev[j]) {
          da = a[j].cross(a[i]);
          dor = a[j].cross(o[i] - o[j]);
        } else {
          dor = a[j];
        }
      }
      if (rev[i]) {
        dv.col(j) += qd[i] * (da.cross(p - o[i]) + a[i].cross(dp - dor));
        dw.col(j) += qd[i] * da;
      } else {
        dv.col(j) += qd[i] * da;
      }
    }
  }
}

}  // namespace detail

void PickupConstraints::eval_g(const double* x, double* g) const {
  for (int s = 0; s < static_cast<int>(samples_.size()); ++s)
    sample_rows(x, s, sample_row_begin_[s], sample_row_begin_[s + 1], g, nullptr);
  sample_rows(x, -1, sample_row_begin_.back(), num_constraints(), g, nullptr);
}

void PickupConstraints::eval_jac(const double* x, double* values) const {
  for (int s = 0; s < static_cast<int>(samples_.size()); ++s)
    sample_rows(x, s, sample_row_begin_[s], sample_row_begin_[s + 1], nullptr, values);
  sample_rows(x, -1, sample_row_begin_.back(), num_constraints(), nullptr, values);
}

void PickupConstraints::kinematics(Kin& k, const double* x, int s, int r0, int r1) const {
  const Sample& S = samples_[s];
  k.T = x[idx_T()];
  k.Sg = x[idx_Sg()];
  k.t = S.w[0] * x[idx_s1()] + S.w[1] * x[idx_s2()] + S.w[2];  // normalised time
  traj_.eval(x, k.t, k.q.data(), k.Ps.data(), k.Pss.data());
  k.qd = k.Ps / k.T;
  k.need_kin = k.need_vel = false;
  for (int r = r0; r < r1; ++r) {
    k.need_kin |= is_kinematic(rows_[r].kind);
    k.need_vel |= (rows_[r].kind == K_VEL || rows_[r].kind == K_OMEGA);
  }
  update_kinematics(k);
}

void PickupConstraints::update_kinematics(Kin& k) const {
  k.c = std::cos(k.q[2]);
  k.sn = std::sin(k.q[2]);
  if (!k.need_kin) return;
  robot_.forward_kinematics(k.q.data(), k.ws);
  if (k.need_vel)
    velocity_derivatives(robot_, k.ws, pb_.tool_link, k.qd, k.Jt, k.dv, k.dw);
  else
    robot_.point_jacobian(k.ws, pb_.tool_link, Eigen::Vector3d::Zero(), k.Jt);
}

bool PickupConstraints::is_kinematic(int kind) {
  return kind == K_VEL || kind == K_OMEGA || kind == K_POSE_P || kind == K_POSE_R || kind == K_POSE_TR ||
         kind == K_COLL;
}

double PickupConstraints::row_partials(const Row& R, Kin& k, Eigen::VectorXd& cq, Eigen::VectorXd& cqd,
                                       double& dsg) const {
  const int n = dof_;
  const Eigen::VectorXd &q = k.q, &Ps = k.Ps, &qd = k.qd;
  const double T = k.T, c = k.c, sn = k.sn;
  cq.setZero();
  cqd.setZero();
  dsg = 0.0;
  double val = 0.0;
  const int a = R.aux;
  switch (R.kind) {
    case K_START:
      val = q[a];
      cq[a] = 1.0;
      break;
    case K_NH:  // |x_s sin phi - y_s cos phi| <= eps L (normalised time: time-scale invariant)
      val = Ps[0] * sn - Ps[1] * c;
      cq[2] = Ps[0] * c + Ps[1] * sn;
      cqd[0] = T * sn;  // c depends on q' only through P_s = T q'
      cqd[1] = -T * c;
      break;
    case K_BSPEED:
      val = qd[0] * qd[0] + qd[1] * qd[1];
      cqd[0] = 2 * qd[0];
      cqd[1] = 2 * qd[1];
      break;
    case K_YAWRATE:
      val = qd[2];
      cqd[2] = 1.0;
      break;
    case K_JPOS:
      val = q[3 + a];
      cq[3 + a] = 1.0;
      break;
    case K_JRATE:
      val = qd[3 + a];
      cqd[3 + a] = 1.0;
      break;
    case K_AREA: {
      const double dx = q[0] - pb_.part_xy[0], dy = q[1] - pb_.part_xy[1];
      val = dx * dx + dy * dy;
      cq[0] = 2 * dx;
      cq[1] = 2 * dy;
      break;
    }
    case K_VEL:
      val = k.Jt.row(a).dot(qd) - k.Sg * pb_.approach_dir[a];
      cq = k.dv.row(a).transpose();
      cqd = k.Jt.row(a).transpose();
      dsg = -pb_.approach_dir[a];
      break;
    case K_OMEGA:
      val = k.Jt.row(3 + a).dot(qd);
      cq = k.dw.row(a).transpose();
      cqd = k.Jt.row(3 + a).transpose();
      break;
    case K_POSE_P:
      val = k.ws.link_pose[pb_.tool_link].p[a] - pb_.grasp_pose.p[a];
      cq = k.Jt.row(a).transpose();
      break;
    case K_POSE_R:
    case K_POSE_TR: {
      const Eigen::Matrix3d& Rt = k.ws.link_pose[pb_.tool_link].R;
      const Eigen::Matrix3d& Rd = pb_.grasp_pose.R;
      Eigen::Vector3d e = Eigen::Vector3d::Zero();
      double tr = 0.0;
      for (int j = 0; j < 3; ++j) {
        e += 0.5 * Rt.col(j).cross(Rd.col(j));
        tr += Rt.col(j).dot(Rd.col(j));
      }
      val = R.kind == K_POSE_R ? e[a] : tr;
      for (int j = 0; j < n; ++j) {
        const Eigen::Vector3d w = k.Jt.block<3, 1>(3, j);
        Eigen::Vector3d de = Eigen::Vector3d::Zero();
        double dtr = 0.0;
        for (int l = 0; l < 3; ++l) {
          const Eigen::Vector3d dr = w.cross(Rt.col(l));
          de += 0.5 * dr.cross(Rd.col(l));
          dtr += dr.dot(Rd.col(l));
        }
        cq[j] = R.kind == K_POSE_R ? de[a] : dtr;
      }
      break;
    }
    case K_GOALPOS: {
      const double dx = q[0] - pb_.goal[0], dy = q[1] - pb_.goal[1];
      val = dx * dx + dy * dy;
      cq[0] = 2 * dx;
      cq[1] = 2 * dy;
      break;
    }
    case K_GOALYAW:  // a heading is an angle: the goal's nearest turn (a route may loop round once)
      val = pb_.goal[2] + std::remainder(q[2] - pb_.goal[2], 2 * M_PI);
      cq[2] = 1.0;
      break;
    case K_COLL: {
      const int no = static_cast<int>(pb_.obstacles.size());
      const BodySphere& b = pb_.body_spheres[a / no];
      const SphereObstacle& o = pb_.obstacles[a % no];
      const Eigen::Vector3d X = k.ws.link_pose[b.link].apply(b.center);
      const Eigen::Vector3d d = X - o.center;
      const double dist = std::max(d.norm(), 1e-12);
      val = dist - b.radius - o.radius;
      robot_.position_jacobian_world(k.ws, b.link, X, k.Jx);
      cq = k.Jx.transpose() * (d / dist);
      break;
    }
    default:
      break;
  }
  return val;
}

void PickupConstraints::sample_rows(const double* x, int s, int r0, int r1, double* g, double* jac) const {
  const double s1 = x[idx_s1()], s2 = x[idx_s2()], T = x[idx_T()], Sg = x[idx_Sg()], Sc = x[idx_Sc()];
  if (s < 0) {  // rows of the time variables and speeds only
    for (int r = r0; r < r1; ++r) {
      const Row& R = rows_[r];
      double* J = jac ? jac + R.jac_begin : nullptr;
      if (R.kind == K_TIMING) {  // (T2 - T1) S_c = stroke
        if (g) g[r] = (s2 - s1) * T * Sc;
        if (J) {
          J[0] = -T * Sc;
          J[1] = T * Sc;
          J[2] = (s2 - s1) * Sc;
          J[3] = (s2 - s1) * T;
        }
      } else if (R.kind == K_RATE_HULL) {  // beta_k / T
        const int i = R.aux / 64, k = R.aux % 64, d = traj_.degree(i);
        const double b = rate_hull_[i].row(k).dot(Eigen::Map<const Eigen::VectorXd>(x + traj_.offset(i), d + 1));
        if (g) g[r] = b / T;
        if (J) {
          for (int l = 0; l <= d; ++l) J[l] = rate_hull_[i](k, l) / T;
          J[d + 1] = -b / (T * T);
        }
      } else if (R.kind == K_ORDER) {
        if (g) g[r] = s2 - s1;
        if (J) {
          J[0] = -1.0;
          J[1] = 1.0;
        }
      } else if (R.kind == K_RHO) {
        if (g) g[r] = pb_.rho.value(Sg, Sc);
        if (J) {
          Eigen::Vector2d d = pb_.rho.gradient(Sg, Sc);
          J[0] = d[0];
          J[1] = d[1];
        }
      }
    }
    return;
  }
  const Sample& S = samples_[s];
  const int n = dof_;
  Kin k(robot_);
  kinematics(k, x, s, r0, r1);
  const double t = k.t;
  double B0[13], B1[13];  // basis values and time derivatives, shared by all DOFs
  if (jac) {
    double p = 1.0;
    B1[0] = 0.0;
    for (int j = 0; j < 13; ++j) {
      B0[j] = p;
      if (j + 1 < 13) B1[j + 1] = (j + 1) * p / T;  // d q' / d a_ik = B'_k(s) / T
      p *= t;
    }
  }
  Eigen::VectorXd cq(n), cqd(n);
  for (int r = r0; r < r1; ++r) {
    const Row& R = rows_[r];
    double dsg = 0.0;
    const double val = row_partials(R, k, cq, cqd, dsg);
    if (g) g[r] = val;
    if (!jac) continue;
    double* J = jac + R.jac_begin;
    int e = 0;
    for (int i = 0; i < n; ++i) {
      if (!(R.dof_mask & (1u << i))) continue;
      for (int j = 0; j <= traj_.degree(i); ++j) J[e++] = cq[i] * B0[j] + cqd[i] * B1[j];
    }
    const double dcds = cq.dot(k.Ps) + cqd.dot(k.Pss) / T;
    for (int v = 0; v < 2; ++v)
      if (S.w[v] != 0.0) J[e++] = dcds * S.w[v];
    J[e++] = R.kind == K_NH ? 0.0 : -cqd.dot(k.qd) / T;
    if (R.sg) J[e++] = dsg;
    if (R.sc) J[e++] = 0.0;
  }
}

Eigen::MatrixXd PickupConstraints::dense_jacobian(const Eigen::VectorXd& x) const {
  core::require_size("NLP variables x", n_, x.size(), "values");
  std::vector<double> v(num_nonzeros());
  eval_jac(x.data(), v.data());
  Eigen::MatrixXd J = Eigen::MatrixXd::Zero(num_constraints(), n_);
  for (int k = 0; k < num_nonzeros(); ++k) J(jac_row_[k], jac_col_[k]) += v[k];
  return J;
}

double PickupConstraints::max_violation(const Eigen::VectorXd& x) const {
  core::require_size("NLP variables x", n_, x.size(), "values");
  Eigen::VectorXd xl, xu, gl, gu, g(num_constraints());
  bounds(xl, xu, gl, gu);
  eval_g(x.data(), g.data());
  double v = 0.0;
  for (int i = 0; i < n_; ++i) v = std::max({v, xl[i] - x[i], x[i] - xu[i]});
  for (int r = 0; r < num_constraints(); ++r) v = std::max({v, gl[r] - g[r], g[r] - gu[r]});
  return v;
}

}  // namespace pickplan::pickup
