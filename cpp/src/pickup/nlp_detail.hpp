#pragma once
// Internals shared by nlp_layout.cpp (rows), nlp.cpp (values, Jacobian), hessian.cpp (Hessian of
// the Lagrangian), rows.cpp (active set), ipopt.cpp and solve.cpp (the solver). Not installed; not
// part of the public API.
#include <string>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {
namespace detail {

enum Kind {
  K_START,
  K_NH,
  K_BSPEED,
  K_YAWRATE,
  K_JPOS,
  K_JRATE,
  K_AREA,
  K_VEL,
  K_OMEGA,
  K_POSE_P,
  K_POSE_R,
  K_POSE_TR,
  K_GOALPOS,
  K_GOALYAW,
  K_COLL,
  K_TIMING,
  K_ORDER,
  K_RHO,
  K_RATE_HULL
};
constexpr double kInf = 2e19;

// Tool-point linear/angular velocity Jacobian J and the derivatives of (J q') with respect to q
// (dv: linear, dw: angular), at the kinematics already in ws.
void velocity_derivatives(const core::Robot& robot, const core::RobotWorkspace& ws, int tool, const Eigen::VectorXd& qd,
                          Eigen::Matrix<double, 6, Eigen::Dynamic>& J, Eigen::Matrix<double, 3, Eigen::Dynamic>& dv,
                          Eigen::Matrix<double, 3, Eigen::Dynamic>& dw);

// True (and why) when no trajectory can place the tool at the grasp position (problem.cpp).
bool grasp_unreachable(const core::Robot& robot, const PickupProblem& pb, std::string& why);

// Ipopt's multipliers: variable bounds (lower, upper) and constraint rows.
struct Multipliers {
  Eigen::VectorXd zl, zu, lambda;
};

// One Ipopt run on a constraint system from x0 (Ipopt's errors are statuses, never exceptions;
// bad options throw std::invalid_argument).
struct IpoptRun {
  SolveStatus status = SolveStatus::not_run;  // Ipopt's return code, shortened
  std::string ipopt_status;                   // ... and in full, as text
  bool converged = false;                     // Solve_Succeeded or Solved_To_Acceptable_Level
  int iterations = 0;
  double seconds = 0.0, cpu_seconds = 0.0;  // wall and thread CPU time
  Eigen::VectorXd x;                        // the final iterate (x0 when Ipopt returned nothing usable)
  Multipliers mult;                         // at the final iterate (empty when Ipopt returned none)
};
// warm (optional): multipliers to start from (Ipopt's warm_start_init_point).
IpoptRun run_ipopt(const PickupConstraints& cons, const PickupSettings& st, const Eigen::VectorXd& x0, double mu_init,
                   const Multipliers* warm = nullptr);
double thread_cpu_seconds();

}  // namespace detail

// Kinematic state at one sample: q, P_s = dq/ds, P_ss, q' = P_s / T, FK and tool Jacobians.
struct PickupConstraints::Kin {
  explicit Kin(const core::Robot& r)
      : q(r.dof()),
        Ps(r.dof()),
        Pss(r.dof()),
        qd(r.dof()),
        ws(r),
        Jt(6, r.dof()),
        dv(3, r.dof()),
        dw(3, r.dof()),
        Jx(3, r.dof()) {}
  double T = 1.0, Sg = 0.0, t = 0.0, c = 1.0, sn = 0.0;
  bool need_kin = false, need_vel = false;
  Eigen::VectorXd q, Ps, Pss, qd;
  core::RobotWorkspace ws;
  Eigen::Matrix<double, 6, Eigen::Dynamic> Jt;
  Eigen::Matrix<double, 3, Eigen::Dynamic> dv, dw, Jx;
};

}  // namespace pickplan::pickup
