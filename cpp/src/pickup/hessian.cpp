// Hessian of the Lagrangian of the pick-up NLP (the objective T is linear, so only constraints).
// Each sampled row is f(q, q', S_g) at s = w0 s1 + w1 s2 + w2 with q = P(s), q' = P_s(s) / T
// (the non-holonomic row: f(q, P_s)). Per sample, the multiplier-weighted rows give a gradient
// and Hessian in z = (q, q') (exact for the polynomial rows; for the forward-kinematics rows,
// forward differences in q of their exact gradients), converted to y = (q, P_s, T) and chained
// through y(a, s, T) (linear in the coefficients a, polynomial in s) into the variables.
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "nlp_detail.hpp"
#include "pickplan/core/errors.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {
using namespace detail;

void PickupConstraints::hess_structure(int* rows, int* cols) const {
  int e = 0;
  for (int i = 0; i < n_; ++i)
    for (int j = 0; j <= i; ++j) {
      rows[e] = i;
      cols[e++] = j;
    }
}

struct PickupConstraints::ZHessian {
  explicit ZHessian(int n)
      : gq(Eigen::VectorXd::Zero(n)),
        gv(Eigen::VectorXd::Zero(n)),
        gp_nh(Eigen::VectorXd::Zero(n)),
        Hqq(Eigen::MatrixXd::Zero(n, n)),
        Hqv(Eigen::MatrixXd::Zero(n, n)),
        Hvv(Eigen::MatrixXd::Zero(n, n)),
        Hqp_nh(Eigen::MatrixXd::Zero(n, n)) {}
  // z = (q, q') accumulators; the non-holonomic rows' terms in (q, P_s) separately.
  Eigen::VectorXd gq, gv, gp_nh;
  Eigen::MatrixXd Hqq, Hqv, Hvv, Hqp_nh;
};

void PickupConstraints::sample_hessian(const double* x, const double* lambda, int s, Eigen::MatrixXd& H) const {
  const int r0 = sample_row_begin_[s], r1 = sample_row_begin_[s + 1];
  bool any = false;
  for (int r = r0; r < r1; ++r) any |= lambda[r] != 0.0;
  if (!any) return;
  Kin k(robot_);
  kinematics(k, x, s, r0, r1);
  ZHessian z(dof_);
  if (z_polynomial_terms(lambda, r0, r1, k, z)) z_kinematic_terms(lambda, r0, r1, k, z);
  chain_to_variables(x, s, k, z, H);
}

// The polynomial rows, exactly; true if a forward-kinematics row has a multiplier.
bool PickupConstraints::z_polynomial_terms(const double* lambda, int r0, int r1, const Kin& k, ZHessian& z) const {
  const Eigen::VectorXd& v = k.qd;
  Eigen::VectorXd &gq = z.gq, &gv = z.gv, &gp_nh = z.gp_nh;
  Eigen::MatrixXd &Hqq = z.Hqq, &Hvv = z.Hvv, &Hqp_nh = z.Hqp_nh;
  bool any_kin = false;
  for (int r = r0; r < r1; ++r) {
    const double l = lambda[r];
    if (l == 0.0) continue;
    const Row& R = rows_[r];
    const int a = R.aux;
    switch (R.kind) {
      case K_START:
        gq[a] += l;
        break;
      case K_JPOS:
        gq[3 + a] += l;
        break;
      case K_GOALYAW:
        gq[2] += l;
        break;
      case K_JRATE:
        gv[3 + a] += l;
        break;
      case K_YAWRATE:
        gv[2] += l;
        break;
      case K_BSPEED:
        gv[0] += 2 * l * v[0];
        gv[1] += 2 * l * v[1];
        Hvv(0, 0) += 2 * l;
        Hvv(1, 1) += 2 * l;
        break;
      case K_AREA:
      case K_GOALPOS: {
        const Eigen::Vector2d ctr = R.kind == K_AREA ? pb_.part_xy : Eigen::Vector2d(pb_.goal.head<2>());
        gq[0] += 2 * l * (k.q[0] - ctr[0]);
        gq[1] += 2 * l * (k.q[1] - ctr[1]);
        Hqq(0, 0) += 2 * l;
        Hqq(1, 1) += 2 * l;
        break;
      }
      case K_NH: {  // f = P_s0 sin(phi) - P_s1 cos(phi)
        const double f = k.Ps[0] * k.sn - k.Ps[1] * k.c;
        gq[2] += l * (k.Ps[0] * k.c + k.Ps[1] * k.sn);
        gp_nh[0] += l * k.sn;
        gp_nh[1] -= l * k.c;
        Hqq(2, 2) -= l * f;
        Hqp_nh(2, 0) += l * k.c;
        Hqp_nh(2, 1) += l * k.sn;
        break;
      }
      default:
        any_kin |= is_kinematic(R.kind);
        break;
    }
  }
  return any_kin;
}

// The forward-kinematics rows: forward differences in q of the weighted exact gradients (linear in q').
void PickupConstraints::z_kinematic_terms(const double* lambda, int r0, int r1, Kin& k, ZHessian& z) const {
  const int n = dof_;
  Eigen::VectorXd G0q(n), G0v(n), Gq(n), Gv(n), cq(n), cqd(n);
  auto weighted = [&](Kin& kk, Eigen::VectorXd& wq, Eigen::VectorXd& wv) {
    wq.setZero();
    wv.setZero();
    double dsg;
    for (int r = r0; r < r1; ++r) {
      if (lambda[r] == 0.0 || !is_kinematic(rows_[r].kind)) continue;
      row_partials(rows_[r], kk, cq, cqd, dsg);
      wq += lambda[r] * cq;
      wv += lambda[r] * cqd;
    }
  };
  weighted(k, G0q, G0v);
  z.gq += G0q;
  z.gv += G0v;
  Kin kp = k;
  Eigen::MatrixXd D(n, n);
  for (int j = 0; j < n; ++j) {
    const double h = 1e-7 * std::max(1.0, std::abs(k.q[j]));
    kp.q = k.q;
    kp.q[j] += h;
    update_kinematics(kp);
    weighted(kp, Gq, Gv);
    D.col(j) = (Gq - G0q) / h;
    z.Hqv.row(j) += ((Gv - G0v) / h).transpose();  // d^2 / dq_j dq'_i
  }
  z.Hqq += 0.5 * (D + D.transpose());
}

// To y = (q, p = P_s, T), then through y(a, t, T) into the coefficients, s1, s2 and T.
void PickupConstraints::chain_to_variables(const double* x, int s, const Kin& k, const ZHessian& z,
                                           Eigen::MatrixXd& H) const {
  const int n = dof_;
  const double T = k.T;
  const Eigen::VectorXd& v = k.qd;
  const Eigen::VectorXd &gq = z.gq, &gv = z.gv, &gp_nh = z.gp_nh;
  const Eigen::MatrixXd &Hqq = z.Hqq, &Hqv = z.Hqv, &Hvv = z.Hvv, &Hqp_nh = z.Hqp_nh;
  // q' = p / T.
  const double T2 = T * T;
  const Eigen::VectorXd gp = gv / T + gp_nh;
  const Eigen::MatrixXd Hqp = Hqv / T + Hqp_nh, Hpp = Hvv / T2;
  const Eigen::VectorXd HqT = -(Hqv * v) / T, HpT = -(Hvv * v) / T2 - gv / T2;
  const double HTT = v.dot(Hvv * v) / T2 + 2.0 * gv.dot(v) / T2;
  // Chain through y(a, t, T): q_i = sum_k a_ik t^k, p_i = sum_k k a_ik t^(k-1).
  const double t = k.t;
  double b0[13], b1[13], b2[13];
  for (int j = 0; j < 13; ++j) {
    b0[j] = std::pow(t, j);
    b1[j] = j >= 1 ? j * std::pow(t, j - 1) : 0.0;
    b2[j] = j >= 2 ? j * (j - 1) * std::pow(t, j - 2) : 0.0;
  }
  Eigen::VectorXd Psss = Eigen::VectorXd::Zero(n);
  for (int i = 0; i < n; ++i)
    for (int j = 3; j <= traj_.degree(i); ++j)
      Psss[i] += x[traj_.offset(i) + j] * j * (j - 1) * (j - 2) * std::pow(t, j - 3);
  const Eigen::VectorXd& Ps = k.Ps;
  const Eigen::VectorXd& Pss = k.Pss;
  const Eigen::VectorXd uq = Hqq * Ps + Hqp * Pss, up = Hqp.transpose() * Ps + Hpp * Pss;
  const double Htt = Ps.dot(Hqq * Ps) + 2.0 * Ps.dot(Hqp * Pss) + Pss.dot(Hpp * Pss) + gq.dot(Pss) + gp.dot(Psss);
  const double HtT = Ps.dot(HqT) + Pss.dot(HpT);
  const Sample& S = samples_[s];
  const int iT = idx_T();
  for (int i = 0; i < n; ++i) {
    const int oi = traj_.offset(i), di = traj_.degree(i);
    for (int j = 0; j < n; ++j) {
      const double hqq = Hqq(i, j), hqp = Hqp(i, j), hpq = Hqp(j, i), hpp = Hpp(i, j);
      if (hqq == 0.0 && hqp == 0.0 && hpq == 0.0 && hpp == 0.0) continue;
      const int oj = traj_.offset(j), dj = traj_.degree(j);
      for (int kk = 0; kk <= di; ++kk)
        for (int ll = 0; ll <= dj; ++ll)
          H(oi + kk, oj + ll) += b0[kk] * (b0[ll] * hqq + b1[ll] * hqp) + b1[kk] * (b0[ll] * hpq + b1[ll] * hpp);
    }
    for (int kk = 0; kk <= di; ++kk) {
      const double hat = b0[kk] * uq[i] + b1[kk] * up[i] + gq[i] * b1[kk] + gp[i] * b2[kk];
      const double haT = b0[kk] * HqT[i] + b1[kk] * HpT[i];
      for (int w = 0; w < 2; ++w) {
        if (S.w[w] == 0.0) continue;
        H(oi + kk, nc_ + w) += S.w[w] * hat;
        H(nc_ + w, oi + kk) += S.w[w] * hat;
      }
      H(oi + kk, iT) += haT;
      H(iT, oi + kk) += haT;
    }
  }
  for (int u = 0; u < 2; ++u) {
    if (S.w[u] == 0.0) continue;
    for (int w = 0; w < 2; ++w) H(nc_ + u, nc_ + w) += S.w[u] * S.w[w] * Htt;
    H(nc_ + u, iT) += S.w[u] * HtT;
    H(iT, nc_ + u) += S.w[u] * HtT;
  }
  H(iT, iT) += HTT;
}

void PickupConstraints::eval_hessian(const double* x, const double* lambda, double* values) const {
  const Eigen::VectorXd lam = Eigen::Map<const Eigen::VectorXd>(lambda, num_constraints());
  const Eigen::MatrixXd H = dense_hessian(Eigen::Map<const Eigen::VectorXd>(x, n_), lam);
  int e = 0;
  for (int i = 0; i < n_; ++i)
    for (int j = 0; j <= i; ++j) values[e++] = H(i, j);
}

Eigen::MatrixXd PickupConstraints::dense_hessian(const Eigen::VectorXd& xv, const Eigen::VectorXd& lambda) const {
  core::require_size("NLP variables x", n_, xv.size(), "values");
  core::require_size("NLP multipliers lambda", num_constraints(), lambda.size(), "values (one per constraint row)");
  const double* x = xv.data();
  Eigen::MatrixXd H = Eigen::MatrixXd::Zero(n_, n_);
  for (int s = 0; s < static_cast<int>(samples_.size()); ++s) sample_hessian(x, lambda.data(), s, H);
  const double s1 = x[idx_s1()], s2 = x[idx_s2()], T = x[idx_T()], Sg = x[idx_Sg()], Sc = x[idx_Sc()];
  auto add = [&](int i, int j, double v) {
    H(i, j) += v;
    if (i != j) H(j, i) += v;
  };
  for (int r = sample_row_begin_.back(); r < num_constraints(); ++r) {
    const double l = lambda[r];
    if (rows_[r].kind == K_TIMING) {  // (s2 - s1) T S_c
      add(idx_s1(), idx_T(), -l * Sc);
      add(idx_s2(), idx_T(), l * Sc);
      add(idx_s1(), idx_Sc(), -l * T);
      add(idx_s2(), idx_Sc(), l * T);
      add(idx_T(), idx_Sc(), l * (s2 - s1));
    } else if (rows_[r].kind == K_RATE_HULL) {  // beta_k(a) / T, beta linear in a
      const int i = rows_[r].aux / 64, k = rows_[r].aux % 64, d = traj_.degree(i);
      const double b = rate_hull_[i].row(k).dot(xv.segment(traj_.offset(i), d + 1));
      for (int l = 0; l <= d; ++l) add(traj_.offset(i) + l, idx_T(), -rate_hull_[i](k, l) * lambda[r] / (T * T));
      add(idx_T(), idx_T(), 2.0 * lambda[r] * b / (T * T * T));
    } else if (rows_[r].kind == K_RHO) {
      const Eigen::Matrix2d h = pb_.rho.hessian(Sg, Sc);
      add(idx_Sg(), idx_Sg(), l * h(0, 0));
      add(idx_Sg(), idx_Sc(), l * h(0, 1));
      add(idx_Sc(), idx_Sc(), l * h(1, 1));
    }
  }
  return H;
}

}  // namespace pickplan::pickup
