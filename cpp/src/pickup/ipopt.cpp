// The Ipopt side of the pick-up NLP: the TNLP adapter (with the Bernstein change of the
// coefficient variables) and one Ipopt run. Ipopt + MUMPS is not thread-safe: one solve at a time
// per process.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include <time.h>

#include <coin/IpIpoptApplication.hpp>
#include <coin/IpIpoptData.hpp>
#include <coin/IpTNLP.hpp>

#include "nlp_detail.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {
using detail::Multipliers;
// -------------------------------------------------------------------------------------
namespace {

// Ipopt's variables z: each DOF's coefficients in the Bernstein basis of its degree on s in [0, 1]
// (control points, on the scale of the joint values) instead of monomials: the monomial basis on
// [0, 1] is badly conditioned (quintics), which showed as huge, heavily damped Newton steps.
// x = M z with M block diagonal (one lower-triangular block per DOF, identity for s1, s2, T, S_g,
// S_c); the constraints are evaluated in x, J_z = J_x M, H_z = M^T H_x M.
class CoeffBasis {
 public:
  CoeffBasis(const PolyTraj& tr, int n, bool bernstein) : M_(Eigen::MatrixXd::Identity(n, n)) {
    if (!bernstein) return;
    for (int i = 0; i < tr.dof(); ++i)
      if (tr.degree(i) + 1 > 16) throw std::invalid_argument("Bernstein basis: degree at most 15");
    for (int i = 0; i < tr.dof(); ++i) {
      const int d = tr.degree(i), o = tr.offset(i);
      for (int k = 0; k <= d; ++k)  // B_{k,d}(s) = C(d,k) s^k (1-s)^(d-k) = sum_j M(j,k) s^j
        for (int j = k; j <= d; ++j) M_(o + j, o + k) = binom(d, k) * binom(d - k, j - k) * ((j - k) % 2 ? -1.0 : 1.0);
    }
    Minv_ = M_.inverse();
    for (int i = 0; i < tr.dof(); ++i) blocks_.push_back({tr.offset(i), tr.degree(i) + 1});
  }
  bool identity() const { return blocks_.empty(); }
  Eigen::VectorXd to_x(const double* z) const { return M_ * Eigen::Map<const Eigen::VectorXd>(z, M_.rows()); }
  Eigen::VectorXd to_z(const Eigen::VectorXd& x) const { return identity() ? x : Eigen::VectorXd(Minv_ * x); }
  // Jacobian values in x -> z: every run of a DOF's coefficient columns (as PickupConstraints lays
  // them out: consecutive, starting at the DOF's offset) times that DOF's block.
  void prepare_jacobian(const int* cols, int nnz) {
    segments_.clear();
    for (int e = 0; e < nnz; ++e)
      for (int b = 0; b < static_cast<int>(blocks_.size()); ++b)
        if (cols[e] == blocks_[b].first) segments_.push_back({e, b});
  }
  void jacobian_to_z(double* values) const {
    double tmp[16];
    for (const auto& [e, b] : segments_) {
      const int o = blocks_[b].first, len = blocks_[b].second;
      for (int k = 0; k < len; ++k) {
        double acc = 0.0;
        for (int j = k; j < len; ++j) acc += values[e + j] * M_(o + j, o + k);  // M lower triangular
        tmp[k] = acc;
      }
      std::copy(tmp, tmp + len, values + e);
    }
  }
  // M^T H M block by block (M is block diagonal; identity outside the coefficient blocks).
  Eigen::MatrixXd hessian_to_z(const Eigen::MatrixXd& H) const {
    if (identity()) return H;
    Eigen::MatrixXd HM = H;  // H M: columns of each block mixed
    for (const auto& [o, len] : blocks_) HM.middleCols(o, len) = H.middleCols(o, len) * M_.block(o, o, len, len);
    Eigen::MatrixXd out = HM;  // M^T (H M): rows of each block mixed
    for (const auto& [o, len] : blocks_)
      out.middleRows(o, len) = M_.block(o, o, len, len).transpose() * HM.middleRows(o, len);
    return out;
  }

 private:
  static double binom(int n, int k) {
    double r = 1.0;
    for (int i = 1; i <= k; ++i) r = r * (n - k + i) / i;
    return r;
  }
  Eigen::MatrixXd M_, Minv_;
  std::vector<std::pair<int, int>> blocks_;    // (offset, length) per DOF
  std::vector<std::pair<int, int>> segments_;  // (first Jacobian entry, DOF)
};

class PickupTNLP : public Ipopt::TNLP {
 public:
  PickupTNLP(const PickupConstraints& c, const Eigen::VectorXd& x0, bool exact_hessian, bool bernstein,
             const Multipliers* warm)
      : x_(x0),
        c_(c),
        basis_(c.traj(), c.num_vars(), bernstein),
        z0_(basis_.to_z(x0)),
        exact_(exact_hessian),
        warm_(warm) {
    std::vector<int> r(c.num_nonzeros()), cl(c.num_nonzeros());
    c.jac_structure(r.data(), cl.data());
    basis_.prepare_jacobian(cl.data(), c.num_nonzeros());
  }
  Eigen::VectorXd x_;  // the solution, in the public (monomial) coefficients
  Multipliers mult;    // at the solution
  int iterations = 0;
  Ipopt::SolverReturn solver_status = Ipopt::UNASSIGNED;
  // Wall-clock deadline of the run (PickupSettings::time_limit): Ipopt 3.11 has no wall-time
  // option, so the callback after each iteration stops it (User_Requested_Stop). It stops when the
  // next iteration, as long as the longest so far (the first: as long as the start-up), would end
  // after the deadline: the budget is a bound on the wall time, not a point at which to start
  // stopping. (The last iteration's length was the guess before: iterations with a line search
  // that backtracks run longer, and cut runs ended 12-18 ms past the deadline.)
  bool has_deadline = false;
  std::chrono::steady_clock::time_point deadline, last_callback;
  std::chrono::steady_clock::duration longest{0};
  bool deadline_hit = false;

  bool intermediate_callback(Ipopt::AlgorithmMode, Ipopt::Index, Ipopt::Number, Ipopt::Number, Ipopt::Number,
                             Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Number, Ipopt::Index,
                             const Ipopt::IpoptData*, Ipopt::IpoptCalculatedQuantities*) override {
    if (!has_deadline) return true;
    const auto now = std::chrono::steady_clock::now();
    longest = std::max(longest, now - last_callback);
    if (now + longest >= deadline) deadline_hit = true;
    last_callback = now;
    return !deadline_hit;
  }

  bool get_nlp_info(Ipopt::Index& n, Ipopt::Index& m, Ipopt::Index& nnz_jac, Ipopt::Index& nnz_h,
                    IndexStyleEnum& style) override {
    n = c_.num_vars();
    m = c_.num_constraints();
    nnz_jac = c_.num_nonzeros();
    nnz_h = exact_ ? c_.num_hess_nonzeros() : 0;
    style = C_STYLE;
    return true;
  }
  bool get_bounds_info(Ipopt::Index n, Ipopt::Number* xl, Ipopt::Number* xu, Ipopt::Index m, Ipopt::Number* gl,
                       Ipopt::Number* gu) override {
    Eigen::VectorXd a, b, c, d;
    c_.bounds(a, b, c, d);  // only s1, s2, T, S_g, S_c are bounded: the same in z
    std::copy(a.data(), a.data() + n, xl);
    std::copy(b.data(), b.data() + n, xu);
    std::copy(c.data(), c.data() + m, gl);
    std::copy(d.data(), d.data() + m, gu);
    return true;
  }
  bool get_starting_point(Ipopt::Index n, bool init_x, Ipopt::Number* x, bool init_z, Ipopt::Number* zl,
                          Ipopt::Number* zu, Ipopt::Index m, bool init_lambda, Ipopt::Number* lambda) override {
    if ((init_z || init_lambda) && !warm_) return false;
    if (init_x) std::copy(z0_.data(), z0_.data() + n, x);
    if (init_z) {
      std::copy(warm_->zl.data(), warm_->zl.data() + n, zl);
      std::copy(warm_->zu.data(), warm_->zu.data() + n, zu);
    }
    if (init_lambda) std::copy(warm_->lambda.data(), warm_->lambda.data() + m, lambda);
    return true;
  }
  bool eval_f(Ipopt::Index, const Ipopt::Number* z, bool, Ipopt::Number& f) override {
    f = z[c_.idx_T()];
    return std::isfinite(f);
  }
  bool eval_grad_f(Ipopt::Index n, const Ipopt::Number*, bool, Ipopt::Number* g) override {
    std::fill(g, g + n, 0.0);
    g[c_.idx_T()] = 1.0;
    return true;
  }
  bool eval_g(Ipopt::Index, const Ipopt::Number* z, bool, Ipopt::Index m, Ipopt::Number* g) override {
    try {
      c_.eval_g(basis_.to_x(z).data(), g);
    } catch (...) {
      return false;
    }
    for (int i = 0; i < m; ++i)
      if (!std::isfinite(g[i])) return false;
    return true;
  }
  bool eval_jac_g(Ipopt::Index, const Ipopt::Number* z, bool, Ipopt::Index, Ipopt::Index nele, Ipopt::Index* rows,
                  Ipopt::Index* cols, Ipopt::Number* values) override {
    try {
      if (values == nullptr) {
        c_.jac_structure(rows, cols);
      } else {
        c_.eval_jac(basis_.to_x(z).data(), values);
        basis_.jacobian_to_z(values);
        for (int i = 0; i < nele; ++i)
          if (!std::isfinite(values[i])) return false;
      }
    } catch (...) {
      return false;
    }
    return true;
  }
  bool eval_h(Ipopt::Index n, const Ipopt::Number* z, bool, Ipopt::Number, Ipopt::Index m, const Ipopt::Number* lambda,
              bool, Ipopt::Index nele, Ipopt::Index* rows, Ipopt::Index* cols, Ipopt::Number* values) override {
    if (!exact_) return false;
    try {
      if (values == nullptr) {
        c_.hess_structure(rows, cols);
      } else {
        const Eigen::MatrixXd H =
            basis_.hessian_to_z(c_.dense_hessian(basis_.to_x(z), Eigen::Map<const Eigen::VectorXd>(lambda, m)));
        int e = 0;
        for (int i = 0; i < n; ++i)
          for (int j = 0; j <= i; ++j) values[e++] = H(i, j);
        for (int i = 0; i < nele; ++i)
          if (!std::isfinite(values[i])) return false;
      }
    } catch (...) {
      return false;
    }
    return true;
  }
  void finalize_solution(Ipopt::SolverReturn status, Ipopt::Index n, const Ipopt::Number* z, const Ipopt::Number* zl,
                         const Ipopt::Number* zu, Ipopt::Index m, const Ipopt::Number*, const Ipopt::Number* lambda,
                         Ipopt::Number, const Ipopt::IpoptData* ip_data, Ipopt::IpoptCalculatedQuantities*) override {
    solver_status = status;
    if (z) x_ = basis_.to_x(z);
    // Multipliers are the same in either coefficient basis (the bounded variables are not mapped).
    if (zl && zu && lambda) {
      mult.zl = Eigen::Map<const Eigen::VectorXd>(zl, n);
      mult.zu = Eigen::Map<const Eigen::VectorXd>(zu, n);
      mult.lambda = Eigen::Map<const Eigen::VectorXd>(lambda, m);
    }
    if (ip_data) iterations = ip_data->iter_count();
  }

 private:
  const PickupConstraints& c_;
  CoeffBasis basis_;
  Eigen::VectorXd z0_;
  bool exact_;
  const Multipliers* warm_;
};

const char* app_status_text(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded:
      return "Solve_Succeeded";
    case Ipopt::Solved_To_Acceptable_Level:
      return "Solved_To_Acceptable_Level";
    case Ipopt::Infeasible_Problem_Detected:
      return "Infeasible_Problem_Detected";
    case Ipopt::Search_Direction_Becomes_Too_Small:
      return "Search_Direction_Becomes_Too_Small";
    case Ipopt::Diverging_Iterates:
      return "Diverging_Iterates";
    case Ipopt::User_Requested_Stop:
      return "User_Requested_Stop";
    case Ipopt::Feasible_Point_Found:
      return "Feasible_Point_Found";
    case Ipopt::Maximum_Iterations_Exceeded:
      return "Maximum_Iterations_Exceeded";
    case Ipopt::Restoration_Failed:
      return "Restoration_Failed";
    case Ipopt::Error_In_Step_Computation:
      return "Error_In_Step_Computation";
    case Ipopt::Maximum_CpuTime_Exceeded:
      return "Maximum_CpuTime_Exceeded";
    case Ipopt::Not_Enough_Degrees_Of_Freedom:
      return "Not_Enough_Degrees_Of_Freedom";
    case Ipopt::Invalid_Problem_Definition:
      return "Invalid_Problem_Definition";
    case Ipopt::Invalid_Option:
      return "Invalid_Option";
    case Ipopt::Invalid_Number_Detected:
      return "Invalid_Number_Detected";
    default:
      return "Internal_Error";
  }
}

SolveStatus short_status(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded:
      return SolveStatus::solved;
    case Ipopt::Solved_To_Acceptable_Level:
      return SolveStatus::solved_acceptable;
    case Ipopt::Infeasible_Problem_Detected:
      return SolveStatus::infeasible;
    case Ipopt::Diverging_Iterates:
      return SolveStatus::diverging;
    case Ipopt::Maximum_Iterations_Exceeded:
      return SolveStatus::max_iterations;
    case Ipopt::Maximum_CpuTime_Exceeded:
      return SolveStatus::max_cpu_time;
    case Ipopt::Restoration_Failed:
      return SolveStatus::restoration_failed;
    case Ipopt::Search_Direction_Becomes_Too_Small:
      return SolveStatus::step_too_small;
    case Ipopt::Invalid_Number_Detected:
      return SolveStatus::invalid_number;
    default:
      return SolveStatus::solver_error;
  }
}

}  // namespace

namespace detail {

double thread_cpu_seconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

IpoptRun run_ipopt(const PickupConstraints& cons, const PickupSettings& st, const Eigen::VectorXd& x0, double mu_init,
                   const Multipliers* warm) {
  IpoptRun res;
  const auto t0 = std::chrono::steady_clock::now();
  const double c0 = thread_cpu_seconds();
  Ipopt::SmartPtr<PickupTNLP> nlp =
      new PickupTNLP(cons, x0, st.hessian == HessianMode::exact, st.basis == CoefficientBasis::bernstein, warm);
  if (st.time_limit > 0) {
    nlp->has_deadline = true;
    nlp->last_callback = t0;
    nlp->deadline = t0 + std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                             std::chrono::duration<double>(st.time_limit));
  }
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  app->Options()->SetIntegerValue("print_level", st.print_level);
  app->Options()->SetStringValue("sb", "yes");
  app->Options()->SetStringValue("hessian_approximation", to_string(st.hessian));
  app->Options()->SetStringValue("mu_strategy", to_string(st.mu_strategy));
  app->Options()->SetNumericValue("mu_init", mu_init);
  if (warm) {
    if (warm->lambda.size() != cons.num_constraints() || warm->zl.size() != cons.num_vars() ||
        warm->zu.size() != cons.num_vars())
      throw std::invalid_argument("warm start: multiplier sizes do not match the constraint system");
    app->Options()->SetStringValue("warm_start_init_point", "yes");
    app->Options()->SetNumericValue("warm_start_bound_push", st.warm_start_push);
    app->Options()->SetNumericValue("warm_start_slack_bound_push", st.warm_start_push);
    app->Options()->SetNumericValue("warm_start_mult_bound_push", st.warm_start_push);
  }
  app->Options()->SetNumericValue("tol", st.tol);
  app->Options()->SetNumericValue("constr_viol_tol", st.constr_viol_tol);
  app->Options()->SetNumericValue("acceptable_constr_viol_tol", std::max(1e-5, st.constr_viol_tol));
  app->Options()->SetIntegerValue("max_iter", st.max_iter);
  app->Options()->SetNumericValue("max_cpu_time", st.max_cpu_time);
  if (st.derivative_test) {
    // First order only: Ipopt's second-order check (forward differences of the Jacobian) is itself
    // off by ~3e-4 here; the Hessian is tested against central differences in the C++ tests.
    app->Options()->SetStringValue("derivative_test", "first-order");
    app->Options()->SetNumericValue("derivative_test_tol", 2e-4);  // forward differences: ~1e-4 at the s1, s2 columns
    app->Options()->SetNumericValue("derivative_test_perturbation", 1e-7);
  }
  for (const auto& [name, value] : st.ipopt_options) {
    // An integer-looking value may still be a numeric option ("tol", "10"): try each kind in turn.
    char* end = nullptr;
    const long iv = std::strtol(value.c_str(), &end, 10);
    const bool is_int = !value.empty() && *end == '\0';
    const double dv = std::strtod(value.c_str(), &end);
    const bool is_num = !value.empty() && *end == '\0';
    bool ok = is_int && app->Options()->SetIntegerValue(name, static_cast<int>(iv), true, true);
    if (!ok && is_num) ok = app->Options()->SetNumericValue(name, dv, true, true);
    if (!ok && !is_num) ok = app->Options()->SetStringValue(name, value, true, true);
    if (!ok) throw std::invalid_argument("invalid Ipopt option " + name + " = " + value);
  }
  Ipopt::ApplicationReturnStatus status = app->Initialize();
  if (!st.output_file.empty() && !app->OpenOutputFile(st.output_file, Ipopt::J_ITERSUMMARY))
    throw std::invalid_argument("cannot open Ipopt output file " + st.output_file);
  if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(Ipopt::GetRawPtr(nlp));
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  res.cpu_seconds = thread_cpu_seconds() - c0;
  res.ipopt_status = app_status_text(status);
  res.status =
      nlp->deadline_hit && status == Ipopt::User_Requested_Stop ? SolveStatus::time_limit : short_status(status);
  res.converged = status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level;
  res.iterations = nlp->iterations;
  res.mult = nlp->mult;
  res.x = nlp->x_;
  if (res.x.size() != x0.size() || !res.x.allFinite()) res.x = x0;
  return res;
}

}  // namespace detail
}  // namespace pickplan::pickup
