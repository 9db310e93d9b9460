// The row layout of the pick-up NLP (Sec. V-A): which constraint rows each stage has at which
// samples, their bounds, the variable bounds and the Jacobian's sparsity; row names and keys for
// diagnostics and warm starts. The values and derivatives of the rows are in nlp.cpp.
#include "nlp_detail.hpp"
#include "pickplan/pickup/nlp.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace pickplan::pickup {
using namespace detail;
namespace {

const char* kKindName[] = {"start",          "nonholonomic",      "base_speed",
                           "yaw_rate",       "joint_position",    "joint_rate",
                           "grasp_area",     "gripper_velocity",  "gripper_angular_velocity",
                           "grasp_position", "grasp_orientation", "grasp_orientation_half",
                           "goal_position",  "goal_yaw",          "collision",
                           "grasp_timing",   "time_order",        "success_probability",
                           "rate_hull"};

}  // namespace

// Optional rows: every one (no subset) or those of the subset; collision rows between samples get
// extra samples (one per distinct instant), after the regular ones.
struct PickupConstraints::RowSelection {
  struct Extra {
    Sample at;
    std::vector<int> joints, pairs;
    bool nonholonomic;
  };
  std::vector<char> joints;             // per (regular sample, arm joint): its limit row is kept
  std::vector<std::vector<int>> pairs;  // per regular sample: the collision pairs kept
  std::vector<Extra> extra;
  Extra& extra_at(const double* w) {
    auto it = std::find_if(extra.begin(), extra.end(),
                           [&](const Extra& e) { return e.at.w[0] == w[0] && e.at.w[1] == w[1] && e.at.w[2] == w[2]; });
    if (it != extra.end()) return *it;
    extra.push_back({{{w[0], w[1], w[2]}}, {}, {}, false});
    return extra.back();
  }
};

PickupConstraints::PickupConstraints(const core::Robot& robot, const PickupProblem& problem,
                                     const PickupSettings& settings, int stage, const PickupRowSubset* subset)
    : robot_(robot), pb_(problem), st_(settings), stage_(stage) {
  if (stage < 0 || stage > 5)
    throw std::invalid_argument("stage must be 0 (all constraints) or 1..5, got " + std::to_string(stage));
  problem.validate(robot);
  if (settings.samples_per_interval < 2)
    throw std::invalid_argument("samples_per_interval must be >= 2, got " +
                                std::to_string(settings.samples_per_interval));
  if (!(settings.dense_nonholonomic >= 0 && std::isfinite(settings.dense_nonholonomic)))
    throw std::invalid_argument("dense_nonholonomic must be a finite number >= 0, got " +
                                std::to_string(settings.dense_nonholonomic));
  dof_ = robot.dof();
  if (dof_ > 31) throw std::invalid_argument("at most 31 DOFs supported");
  const std::vector<int> deg = resolved_degrees(settings, dof_);
  if (static_cast<int>(deg.size()) != dof_)
    throw std::invalid_argument("degrees: expected " + std::to_string(dof_) + " values, got " +
                                std::to_string(deg.size()));
  traj_ = PolyTraj(deg, 1.0);
  // S_g above this bound can never meet rho >= gamma: bounding it in every stage (not only from
  // stage 4 on, where the probability row enforces it) keeps stage 3 from driving the gripper to
  // a speed stage 4 must then undo.
  sg_cap_ = problem.vary_sc ? problem.rho.sg_upper_bound(problem.gamma, problem.rho.sc_lo, problem.rho.sc_hi)
                            : problem.rho.sg_upper_bound(problem.gamma, problem.sc_fixed, problem.sc_fixed);
  nc_ = traj_.num_coeffs();
  n_ = nc_ + 5;
  level_ = stage == 0 ? 5 : stage;
  if (settings.rate_rows == RateRows::hull) build_rate_hull();
  place_samples(settings.samples_per_interval);
  const double nh_bound = settings.nonholonomic_tol * ((problem.part_xy - problem.start.head<2>()).norm() +
                                                       (problem.goal.head<2>() - problem.part_xy).norm());
  nreg_ = static_cast<int>(samples_.size());
  const RowSelection sel = select_rows(subset);
  for (const auto& b : problem.body_spheres) {
    unsigned mask = 0;
    for (int i = 0; i < dof_; ++i)
      if (robot.moves(i, b.link)) mask |= 1u << i;
    body_mask_.push_back(mask);
  }
  add_sample_rows(sel, nh_bound);
  sample_row_begin_.push_back(static_cast<int>(rows_.size()));
  // Yaw and arm joint rates over all of [0, T]: the hull of the rate's Bernstein points.
  if (settings.rate_rows == RateRows::hull) {
    for (int i = 2; i < dof_; ++i) {
      const double lim = i == 2 ? problem.base_yaw_rate_limit : problem.arm_rate_limits[i - 3];
      for (int k = 0; k < rate_hull_[i].rows(); ++k) add_row(K_RATE_HULL, -1, i * 64 + k, 0, false, false, -lim, lim);
    }
  }
  add_row(K_TIMING, -1, 0, 0, false, true, problem.stroke, problem.stroke);
  add_row(K_ORDER, -1, 0, 0, false, false, 0.0, kInf);
  if (level_ >= 4) add_row(K_RHO, -1, 0, 0, true, true, problem.gamma, kInf);
}

// P_s of DOF i (degree d - 1, monomial p_l = (l + 1) a_{l+1}) in the Bernstein basis of degree n:
// beta_k = sum_{l <= k} C(k, l) / C(n, l) p_l. |P_s| <= max_k |beta_k| on [0, 1] (convex hull).
void PickupConstraints::build_rate_hull() {
  const int n = st_.rate_hull_degree;
  if (n < 1 || n > 60) throw std::invalid_argument("rate_hull_degree must be in [1, 60], got " + std::to_string(n));
  auto binom = [](int a, int b) {
    double r = 1.0;
    for (int i = 1; i <= b; ++i) r = r * (a - b + i) / i;
    return r;
  };
  rate_hull_.assign(dof_, Eigen::MatrixXd());
  for (int i = 2; i < dof_; ++i) {
    const int d = traj_.degree(i), nn = std::max(n, d - 1);
    Eigen::MatrixXd E = Eigen::MatrixXd::Zero(nn + 1, d + 1);
    for (int k = 0; k <= nn; ++k)
      for (int l = 0; l <= std::min(k, d - 1); ++l) E(k, l + 1) = (l + 1) * binom(k, l) / binom(nn, l);
    rate_hull_[i] = E;
  }
}

// m samples per interval: [0, s1), [s1, s2] (both ends), (s2, 1].
void PickupConstraints::place_samples(int m) {
  for (int j = 0; j < m; ++j) samples_.push_back({{double(j) / m, 0.0, 0.0}});
  for (int j = 0; j < m; ++j) {
    double u = double(j) / (m - 1);
    samples_.push_back({{1.0 - u, u, 0.0}});
  }
  for (int j = 1; j <= m; ++j) {
    double u = double(j) / m;
    samples_.push_back({{0.0, 1.0 - u, u}});
  }
}

PickupConstraints::RowSelection PickupConstraints::select_rows(const PickupRowSubset* subset) {
  const int na = dof_ - 3;
  RowSelection sel;
  sel.joints.assign(nreg_ * na, subset ? 0 : 1);
  sel.pairs.resize(nreg_);
  const int npairs = static_cast<int>(pb_.obstacles.size()) * static_cast<int>(pb_.body_spheres.size());
  if (subset) {
    for (const auto& j : subset->joints) {
      if (j.sample >= nreg_ || j.joint < 0 || j.joint >= na)
        throw std::invalid_argument("row subset: joint row (sample " + std::to_string(j.sample) + ", joint " +
                                    std::to_string(j.joint) + ") out of range");
      if (j.sample >= 0)
        sel.joints[j.sample * na + j.joint] = 1;
      else
        sel.extra_at(j.w).joints.push_back(j.joint);
    }
    for (const auto& c : subset->collisions) {
      if (c.pair < 0 || c.pair >= npairs || c.sample >= nreg_)
        throw std::invalid_argument("row subset: collision row (sample " + std::to_string(c.sample) + ", pair " +
                                    std::to_string(c.pair) + ") out of range");
      if (c.sample >= 0)
        sel.pairs[c.sample].push_back(c.pair);
      else
        sel.extra_at(c.w).pairs.push_back(c.pair);
    }
    for (const auto& n : subset->nonholonomic) sel.extra_at(n.w).nonholonomic = true;
  } else {
    for (auto& v : sel.pairs)
      for (int p = 0; p < npairs; ++p) v.push_back(p);
  }
  for (auto& v : sel.pairs) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }
  for (auto& e : sel.extra) {
    samples_.push_back(e.at);
    for (auto* v : {&e.joints, &e.pairs}) {
      std::sort(v->begin(), v->end());
      v->erase(std::unique(v->begin(), v->end()), v->end());
    }
  }
  return sel;
}

void PickupConstraints::add_joint_row(int s, int j) {
  const double lo = robot_.lower_limits()[3 + j], hi = robot_.upper_limits()[3 + j];
  if (std::isfinite(lo) || std::isfinite(hi))
    add_row(K_JPOS, s, j, 1u << (3 + j), false, false, std::isfinite(lo) ? lo + st_.joint_limit_margin : -kInf,
            std::isfinite(hi) ? hi - st_.joint_limit_margin : kInf);
}

void PickupConstraints::add_collision_rows(int s, const std::vector<int>& pairs) {
  const int no = static_cast<int>(pb_.obstacles.size());
  for (int p : pairs)
    if (pair_in_stage(p)) add_row(K_COLL, s, p, body_mask_[p / no], false, false, st_.collision_margin, kInf);
}

// The rows of every regular sample, then of the extra samples.
void PickupConstraints::add_sample_rows(const RowSelection& sel, double nh_bound) {
  const PickupProblem& problem = pb_;
  const int m = st_.samples_per_interval, na = dof_ - 3;
  const bool hull = st_.rate_rows == RateRows::hull;
  const unsigned all = (dof_ == 32) ? ~0u : ((1u << dof_) - 1u), base = 7u;
  const double vt = st_.velocity_tol, wt = st_.angular_velocity_tol;
  for (int s = 0; s < nreg_; ++s) {
    sample_row_begin_.push_back(static_cast<int>(rows_.size()));
    const int interval = s / m;
    // The start configuration is q(0) = a_i0: variable bounds (bounds()), not rows.
    add_row(K_NH, s, 0, base, false, false, -nh_bound, nh_bound);
    add_row(K_BSPEED, s, 0, base, false, false, -kInf, problem.base_speed_limit * problem.base_speed_limit);
    if (!hull) add_row(K_YAWRATE, s, 0, base, false, false, -problem.base_yaw_rate_limit, problem.base_yaw_rate_limit);
    for (int j = 0; j < na; ++j) {
      if (s > 0 && sel.joints[s * na + j]) add_joint_row(s, j);  // q(0) is fixed
      if (!hull)
        add_row(K_JRATE, s, j, 1u << (3 + j), false, false, -problem.arm_rate_limits[j], problem.arm_rate_limits[j]);
    }
    if (interval == 1) {
      add_row(K_AREA, s, 0, base, false, false, problem.grasp_area_rmin * problem.grasp_area_rmin,
              problem.grasp_area_rmax * problem.grasp_area_rmax);
      if (level_ >= 3) {
        for (int i = 0; i < 3; ++i) add_row(K_VEL, s, i, all, true, false, -vt, vt);
        for (int i = 0; i < 3; ++i) add_row(K_OMEGA, s, i, all, false, false, -wt, wt);
      }
      if (level_ >= 2 && s == 2 * m - 1) {
        for (int i = 0; i < 3; ++i) add_row(K_POSE_P, s, i, all, false, false, 0.0, 0.0);
        for (int i = 0; i < 3; ++i) add_row(K_POSE_R, s, i, all, false, false, 0.0, 0.0);
        add_row(K_POSE_TR, s, 0, all, false, false, 1.0, kInf);
      }
    }
    if (s == 3 * m - 1) {
      add_row(K_GOALPOS, s, 0, base, false, false, -kInf, problem.goal_tol_pos * problem.goal_tol_pos);
      add_row(K_GOALYAW, s, 0, base, false, false, problem.goal[2] - problem.goal_tol_yaw,
              problem.goal[2] + problem.goal_tol_yaw);
    }
    add_collision_rows(s, sel.pairs[s]);
  }
  for (int e = 0; e < static_cast<int>(sel.extra.size()); ++e) {
    sample_row_begin_.push_back(static_cast<int>(rows_.size()));
    if (sel.extra[e].nonholonomic) add_row(K_NH, nreg_ + e, 0, base, false, false, -nh_bound, nh_bound);
    for (int j : sel.extra[e].joints) add_joint_row(nreg_ + e, j);
    add_collision_rows(nreg_ + e, sel.extra[e].pairs);
  }
}

void PickupConstraints::add_row(int kind, int sample, int aux, unsigned mask, bool sg, bool sc, double lo, double hi) {
  Row r{kind, sample, aux, mask, sg, sc, lo, hi, static_cast<int>(jac_col_.size())};
  const int row = static_cast<int>(rows_.size());
  auto push = [&](int col) {
    jac_row_.push_back(row);
    jac_col_.push_back(col);
  };
  if (sample >= 0) {
    for (int i = 0; i < dof_; ++i)
      if (mask & (1u << i))
        for (int k = 0; k <= traj_.degree(i); ++k) push(traj_.offset(i) + k);
    for (int v = 0; v < 2; ++v)
      if (samples_[sample].w[v] != 0.0) push(nc_ + v);
    push(idx_T());
  } else if (kind == K_TIMING) {
    push(idx_s1());
    push(idx_s2());
    push(idx_T());
  } else if (kind == K_ORDER) {
    push(idx_s1());
    push(idx_s2());
  } else if (kind == K_RATE_HULL) {
    const int i = aux / 64;
    for (int k = 0; k <= traj_.degree(i); ++k) push(traj_.offset(i) + k);
    push(idx_T());
  }
  if (sg) push(idx_Sg());
  if (sc) push(idx_Sc());
  rows_.push_back(r);
}

void PickupConstraints::bounds(Eigen::VectorXd& xl, Eigen::VectorXd& xu, Eigen::VectorXd& gl,
                               Eigen::VectorXd& gu) const {
  xl = Eigen::VectorXd::Constant(n_, -kInf);
  xu = Eigen::VectorXd::Constant(n_, kInf);
  for (int i = 0; i < dof_; ++i)  // q(0) = a_i0: the start configuration
    xl[traj_.offset(i)] = xu[traj_.offset(i)] = i < 3 ? pb_.start[i] : pb_.arm_start[i - 3];
  xl[idx_s1()] = 0.0;
  xu[idx_s1()] = 1.0;
  xl[idx_s2()] = 0.0;
  xu[idx_s2()] = 1.0;
  xl[idx_T()] = st_.t_min;
  xu[idx_T()] = st_.t_max;
  xl[idx_Sg()] = pb_.rho.sg_lo;
  xu[idx_Sg()] = std::isnan(sg_cap_) ? pb_.rho.sg_hi : sg_cap_;
  xl[idx_Sc()] = pb_.vary_sc ? pb_.rho.sc_lo : pb_.sc_fixed;
  xu[idx_Sc()] = pb_.vary_sc ? pb_.rho.sc_hi : pb_.sc_fixed;
  const int mrows = num_constraints();
  gl.resize(mrows);
  gu.resize(mrows);
  for (int r = 0; r < mrows; ++r) {
    gl[r] = rows_[r].lo;
    gu[r] = rows_[r].hi;
  }
}

void PickupConstraints::jac_structure(int* rows, int* cols) const {
  std::copy(jac_row_.begin(), jac_row_.end(), rows);
  std::copy(jac_col_.begin(), jac_col_.end(), cols);
}

bool PickupConstraints::pair_in_stage(int pair) const {
  if (pb_.obstacles.empty()) return false;
  return level_ >= 5 || (body_mask_.at(pair / static_cast<int>(pb_.obstacles.size())) & ~7u) == 0u;
}

bool PickupConstraints::has_collision_rows() const {
  const int npairs = static_cast<int>(pb_.obstacles.size() * pb_.body_spheres.size());
  for (int p = 0; p < npairs; ++p)
    if (pair_in_stage(p)) return true;
  return false;
}

std::array<double, 5> PickupConstraints::row_key(int r) const {
  const Row& R = rows_.at(r);
  if (R.sample < 0) return {double(R.kind), -1.0, -1.0, -1.0, double(R.aux)};
  const Sample& S = samples_[R.sample];
  return {double(R.kind), S.w[0], S.w[1], S.w[2], double(R.aux)};
}

std::vector<std::string> PickupConstraints::row_names() const {
  std::vector<std::string> out;
  for (const Row& r : rows_)
    out.push_back(std::string(kKindName[r.kind]) + "[" + std::to_string(r.aux) + "]@" + std::to_string(r.sample));
  return out;
}

}  // namespace pickplan::pickup