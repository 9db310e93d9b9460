// Ipopt driver of the pick-up NLP: the TNLP adapter, seeds, the five stages of successive
// refinement (Sec. V-B) and the single-shot baseline. Ipopt + MUMPS is not thread-safe: one
// solve at a time per process.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <stdexcept>

#include <coin/IpIpoptApplication.hpp>
#include <coin/IpIpoptData.hpp>
#include <coin/IpTNLP.hpp>

#include "pickplan/pickup_nlp.hpp"

namespace pickplan {

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
                                std::to_string(sg_hi) + "], S_c [" + std::to_string(sc_lo) + ", " + std::to_string(sc_hi) + "]");
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
  const double u = std::clamp((sg - sg_lo) / (sg_hi - sg_lo), 0.0, 1.0), v = std::clamp((sc - sc_lo) / (sc_hi - sc_lo), 0.0, 1.0);
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

void PickupProblem::validate(const Robot& robot) const {
  const int na = robot.dof() - 3;
  if (na < 1) throw std::invalid_argument("robot: expected 3 base DOFs plus an arm, got " + std::to_string(robot.dof()) + " DOFs");
  if (arm_start.size() != na)
    throw std::invalid_argument("arm_start: expected " + std::to_string(na) + " joint values, got " + std::to_string(arm_start.size()));
  if (arm_rate_limits.size() != na)
    throw std::invalid_argument("arm_rate_limits: expected " + std::to_string(na) + " values, got " + std::to_string(arm_rate_limits.size()));
  if ((arm_rate_limits.array() <= 0).any()) throw std::invalid_argument("arm_rate_limits must be positive");
  if (tool_link < 0 || tool_link >= robot.num_links()) throw std::invalid_argument("tool_link: index out of range");
  if (std::abs(approach_dir.norm() - 1.0) > 1e-6) throw std::invalid_argument("approach_dir must be a unit vector");
  if (!(grasp_area_rmax > grasp_area_rmin) || grasp_area_rmin < 0)
    throw std::invalid_argument("grasp area: expected 0 <= rmin < rmax");
  if (!(gamma >= 0 && gamma <= 1)) throw std::invalid_argument("gamma must lie in [0, 1], got " + std::to_string(gamma));
  if (!(stroke > 0)) throw std::invalid_argument("stroke must be positive");
  if (!(base_speed_limit > 0) || !(base_yaw_rate_limit > 0)) throw std::invalid_argument("base limits must be positive");
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

namespace {
int num_vars(const Robot& robot, const PickupSettings& st) {
  std::vector<int> deg = st.degrees.empty() ? default_degrees(robot.dof()) : st.degrees;
  return PolyTraj(deg, 1.0).num_coeffs() + 5;
}
}  // namespace

// ---- Ipopt -------------------------------------------------------------------------------------
namespace {

class PickupTNLP : public Ipopt::TNLP {
 public:
  PickupTNLP(const PickupConstraints& c, const Eigen::VectorXd& x0, bool exact_hessian)
      : x_(x0), c_(c), x0_(x0), exact_(exact_hessian) {}
  Eigen::VectorXd x_;
  int iterations = 0;
  Ipopt::SolverReturn solver_status = Ipopt::UNASSIGNED;

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
    c_.bounds(a, b, c, d);
    std::copy(a.data(), a.data() + n, xl);
    std::copy(b.data(), b.data() + n, xu);
    std::copy(c.data(), c.data() + m, gl);
    std::copy(d.data(), d.data() + m, gu);
    return true;
  }
  bool get_starting_point(Ipopt::Index n, bool init_x, Ipopt::Number* x, bool init_z, Ipopt::Number*, Ipopt::Number*,
                          Ipopt::Index, bool init_lambda, Ipopt::Number*) override {
    if (init_z || init_lambda) return false;
    if (init_x) std::copy(x0_.data(), x0_.data() + n, x);
    return true;
  }
  bool eval_f(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number& f) override {
    f = x[c_.idx_T()];
    return std::isfinite(f);
  }
  bool eval_grad_f(Ipopt::Index n, const Ipopt::Number*, bool, Ipopt::Number* g) override {
    std::fill(g, g + n, 0.0);
    g[c_.idx_T()] = 1.0;
    return true;
  }
  bool eval_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index m, Ipopt::Number* g) override {
    try {
      c_.eval_g(x, g);
    } catch (...) {
      return false;
    }
    for (int i = 0; i < m; ++i)
      if (!std::isfinite(g[i])) return false;
    return true;
  }
  bool eval_jac_g(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Index, Ipopt::Index nele, Ipopt::Index* rows,
                  Ipopt::Index* cols, Ipopt::Number* values) override {
    try {
      if (values == nullptr) {
        c_.jac_structure(rows, cols);
      } else {
        c_.eval_jac(x, values);
        for (int i = 0; i < nele; ++i)
          if (!std::isfinite(values[i])) return false;
      }
    } catch (...) {
      return false;
    }
    return true;
  }
  bool eval_h(Ipopt::Index, const Ipopt::Number* x, bool, Ipopt::Number, Ipopt::Index, const Ipopt::Number* lambda,
              bool, Ipopt::Index nele, Ipopt::Index* rows, Ipopt::Index* cols, Ipopt::Number* values) override {
    if (!exact_) return false;
    try {
      if (values == nullptr) {
        c_.hess_structure(rows, cols);
      } else {
        c_.eval_hessian(x, lambda, values);
        for (int i = 0; i < nele; ++i)
          if (!std::isfinite(values[i])) return false;
      }
    } catch (...) {
      return false;
    }
    return true;
  }
  void finalize_solution(Ipopt::SolverReturn status, Ipopt::Index n, const Ipopt::Number* x, const Ipopt::Number*,
                         const Ipopt::Number*, Ipopt::Index, const Ipopt::Number*, const Ipopt::Number*, Ipopt::Number,
                         const Ipopt::IpoptData* ip_data, Ipopt::IpoptCalculatedQuantities*) override {
    solver_status = status;
    if (x) x_ = Eigen::Map<const Eigen::VectorXd>(x, n);
    if (ip_data) iterations = ip_data->iter_count();
  }

 private:
  const PickupConstraints& c_;
  Eigen::VectorXd x0_;
  bool exact_;
};

const char* app_status_text(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded: return "Solve_Succeeded";
    case Ipopt::Solved_To_Acceptable_Level: return "Solved_To_Acceptable_Level";
    case Ipopt::Infeasible_Problem_Detected: return "Infeasible_Problem_Detected";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "Search_Direction_Becomes_Too_Small";
    case Ipopt::Diverging_Iterates: return "Diverging_Iterates";
    case Ipopt::User_Requested_Stop: return "User_Requested_Stop";
    case Ipopt::Feasible_Point_Found: return "Feasible_Point_Found";
    case Ipopt::Maximum_Iterations_Exceeded: return "Maximum_Iterations_Exceeded";
    case Ipopt::Restoration_Failed: return "Restoration_Failed";
    case Ipopt::Error_In_Step_Computation: return "Error_In_Step_Computation";
    case Ipopt::Maximum_CpuTime_Exceeded: return "Maximum_CpuTime_Exceeded";
    case Ipopt::Not_Enough_Degrees_Of_Freedom: return "Not_Enough_Degrees_Of_Freedom";
    case Ipopt::Invalid_Problem_Definition: return "Invalid_Problem_Definition";
    case Ipopt::Invalid_Option: return "Invalid_Option";
    case Ipopt::Invalid_Number_Detected: return "Invalid_Number_Detected";
    default: return "Internal_Error";
  }
}

const char* short_status(Ipopt::ApplicationReturnStatus s) {
  switch (s) {
    case Ipopt::Solve_Succeeded: return "solved";
    case Ipopt::Solved_To_Acceptable_Level: return "solved_acceptable";
    case Ipopt::Infeasible_Problem_Detected: return "infeasible";
    case Ipopt::Diverging_Iterates: return "diverging";
    case Ipopt::Maximum_Iterations_Exceeded: return "max_iterations";
    case Ipopt::Maximum_CpuTime_Exceeded: return "max_cpu_time";
    case Ipopt::Restoration_Failed: return "restoration_failed";
    case Ipopt::Search_Direction_Becomes_Too_Small: return "step_too_small";
    case Ipopt::Invalid_Number_Detected: return "invalid_number";
    default: return "solver_error";
  }
}

}  // namespace

namespace {
// Sound reachability test of the grasp position: the tool is at most R (sum of the fixed link
// offsets from the first arm joint to the tool, triangle inequality) from the first arm joint, whose
// position is fixed on the base; if even the nearest base pose in the grasping area leaves the grasp
// point farther than R, no trajectory can satisfy the grasp-pose constraint.
bool grasp_unreachable(const Robot& robot, const PickupProblem& pb, std::string& why) {
  const int first = robot.link_of_q(3);
  double reach = 0.0;
  for (int k = pb.tool_link; k >= 0 && k != first; k = robot.link(k).parent) {
    if (robot.link(k).joint_type == JointType::Prismatic) return false;  // no bound for prismatic arms
    reach += robot.link(k).joint_origin.p.norm();
  }
  RobotWorkspace ws(robot);
  Eigen::VectorXd q = Eigen::VectorXd::Zero(robot.dof());
  robot.forward_kinematics(q.data(), ws);
  const Eigen::Vector3d j0 = ws.link_pose[first].p - robot.base().p;
  const double mount = j0.head<2>().norm();
  const double dz = pb.grasp_pose.p.z() - (robot.base().p.z() + j0.z());
  const double dxy_part = (pb.grasp_pose.p.head<2>() - pb.part_xy).norm();
  const double h = std::max(0.0, pb.grasp_area_rmin - mount - dxy_part);
  const double dmin = std::hypot(dz, h);
  if (dmin <= reach) return false;
  why = "grasp point at least " + std::to_string(dmin) + " m from the first arm joint, reach " + std::to_string(reach) + " m";
  return true;
}
}  // namespace

StageResult solve_stage(const Robot& robot, const PickupProblem& pb, const PickupSettings& st, int stage,
                        const Eigen::VectorXd& x0) {
  PickupConstraints cons(robot, pb, st, stage);  // validates (throws std::invalid_argument)
  if (x0.size() != cons.num_vars())
    throw std::invalid_argument("seed: expected " + std::to_string(cons.num_vars()) + " variables, got " + std::to_string(x0.size()));
  if (!x0.allFinite()) throw std::invalid_argument("seed: values must be finite");
  const double T = x0[cons.idx_T()], T1 = x0[cons.idx_s1()] * T, T2 = x0[cons.idx_s2()] * T;
  if (!(T > 0 && x0[cons.idx_s1()] >= 0.0 && x0[cons.idx_s1()] <= x0[cons.idx_s2()] && x0[cons.idx_s2()] <= 1.0))
    throw std::invalid_argument("seed: inconsistent time ordering, expected 0 <= T1 <= T2 <= T, got T1=" +
                                std::to_string(T1) + " T2=" + std::to_string(T2) + " T=" + std::to_string(T));
  StageResult res;
  res.stage = stage;
  std::string why;
  if ((stage == 0 || stage >= 2) && grasp_unreachable(robot, pb, why)) {
    res.status = "infeasible";
    res.ipopt_status = "Not_Solved (reachability pre-check: " + why + ")";
    res.x = x0;
    res.objective = x0[cons.idx_T()];
    res.max_violation = cons.max_violation(x0);
    return res;
  }
  const auto t0 = std::chrono::steady_clock::now();
  if (st.hessian != "exact" && st.hessian != "limited-memory")
    throw std::invalid_argument("hessian must be \"exact\" or \"limited-memory\", got \"" + st.hessian + "\"");
  Ipopt::SmartPtr<PickupTNLP> nlp = new PickupTNLP(cons, x0, st.hessian == "exact");
  Ipopt::SmartPtr<Ipopt::IpoptApplication> app = IpoptApplicationFactory();
  app->Options()->SetIntegerValue("print_level", st.print_level);
  app->Options()->SetStringValue("sb", "yes");
  app->Options()->SetStringValue("hessian_approximation", st.hessian);
  app->Options()->SetStringValue("mu_strategy", st.mu_strategy);
  app->Options()->SetNumericValue("mu_init", st.mu_init);
  app->Options()->SetNumericValue("tol", st.tol);
  app->Options()->SetNumericValue("constr_viol_tol", st.constr_viol_tol);
  app->Options()->SetNumericValue("acceptable_constr_viol_tol", std::max(1e-5, st.constr_viol_tol));
  app->Options()->SetIntegerValue("max_iter", st.max_iter);
  app->Options()->SetNumericValue("max_cpu_time", st.max_cpu_time);
  if (st.derivative_test) {
    // First order only: Ipopt's second-order check (forward differences of the Jacobian) is itself
    // off by ~3e-4 here; the Hessian is tested against central differences in the C++ tests.
    app->Options()->SetStringValue("derivative_test", "first-order");
    app->Options()->SetNumericValue("derivative_test_tol", 1e-4);
    app->Options()->SetNumericValue("derivative_test_perturbation", 1e-7);
  }
  for (const auto& [name, value] : st.ipopt_options) {
    char* end = nullptr;
    const long iv = std::strtol(value.c_str(), &end, 10);
    bool ok;
    if (!value.empty() && *end == '\0') {
      ok = app->Options()->SetIntegerValue(name, static_cast<int>(iv));
    } else {
      const double dv = std::strtod(value.c_str(), &end);
      ok = (!value.empty() && *end == '\0') ? app->Options()->SetNumericValue(name, dv)
                                             : app->Options()->SetStringValue(name, value);
    }
    if (!ok) throw std::invalid_argument("invalid Ipopt option " + name + " = " + value);
  }
  Ipopt::ApplicationReturnStatus status = app->Initialize();
  if (!st.output_file.empty() && !app->OpenOutputFile(st.output_file, Ipopt::J_ITERSUMMARY))
    throw std::invalid_argument("cannot open Ipopt output file " + st.output_file);
  if (status == Ipopt::Solve_Succeeded) status = app->OptimizeTNLP(Ipopt::GetRawPtr(nlp));
  res.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  res.ipopt_status = app_status_text(status);
  res.status = short_status(status);
  res.iterations = nlp->iterations;
  res.x = nlp->x_;
  if (res.x.size() != x0.size() || !res.x.allFinite()) res.x = x0;
  res.objective = res.x[cons.idx_T()];
  res.max_violation = cons.max_violation(res.x);
  res.success = (status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level) &&
                res.max_violation <= std::max(1e-4, 10 * st.constr_viol_tol);
  if (!res.success && (status == Ipopt::Solve_Succeeded || status == Ipopt::Solved_To_Acceptable_Level))
    res.status = "constraint_violation";
  return res;
}

namespace {
void fill_result(PickupResult& out, const Robot& robot, const PickupSettings& st) {
  std::vector<int> deg = st.degrees.empty() ? default_degrees(robot.dof()) : st.degrees;
  const int nc = PolyTraj(deg, 1.0).num_coeffs();
  out.T = out.x[nc + 2];
  out.T1 = out.x[nc] * out.T;
  out.T2 = out.x[nc + 1] * out.T;
  out.traj = PolyTraj(deg, out.T);
  out.S_g = out.x[nc + 3];
  out.S_c = out.x[nc + 4];
  for (const auto& s : out.stages) out.total_seconds += s.seconds;
}
}  // namespace

PickupResult solve_successive(const Robot& robot, const PickupProblem& pb, const PickupSettings& st,
                              const Eigen::VectorXd& x0) {
  PickupResult out;
  out.x = x0.size() ? x0 : heuristic_seed(robot, pb, st);
  if (out.x.size() != num_vars(robot, st))
    throw std::invalid_argument("seed: expected " + std::to_string(num_vars(robot, st)) + " variables, got " + std::to_string(out.x.size()));
  out.status = "solved";
  out.success = true;
  for (int stage = 1; stage <= 5; ++stage) {
    // Stage 2 adds the grasp pose: its arm seed comes from an IK solution at T2 (base as stage 1).
    StageResult r = solve_stage(robot, pb, st, stage, stage == 2 ? grasp_ik_seed(robot, pb, st, out.x) : out.x);
    out.stages.push_back(r);
    if (!r.success) {
      out.status = r.status;
      out.success = false;
      break;
    }
    out.x = r.x;
    out.stages_completed = stage;
  }
  fill_result(out, robot, st);
  return out;
}

PickupResult solve_single_shot(const Robot& robot, const PickupProblem& pb, const PickupSettings& st) {
  PickupResult out;
  const Eigen::VectorXd seed = random_seed(robot, pb, st);
  StageResult r = solve_stage(robot, pb, st, 0, seed);
  out.stages.push_back(r);
  out.status = r.status;
  out.success = r.success;
  out.stages_completed = r.success ? 5 : 0;
  out.x = r.success ? r.x : seed;
  fill_result(out, robot, st);
  return out;
}

}  // namespace pickplan
