#pragma once
// Goal selection policies (OMG Sec. III-D), native: Fixed, Proj, FTC, FTL, EXP and Mirror Descent,
// the same rules as python/pickplan/omg/selection.py (the research reference they are tested
// against), so the Algorithm 2 loop runs without Python. Reductions follow numpy's order (its
// pairwise sum) so both give the same numbers up to exp/log round-off.
#include <vector>

#include <Eigen/Core>

namespace pickplan::omg {

enum class SelectionKind { Fixed, Proj, FTC, FTL, EXP, MD };
enum class CostKind { objective, distance };  // goal-cost estimates (eq. 8) | free end point's distance (Proj)

struct SelectionSettings {
  SelectionKind kind = SelectionKind::MD;
  double exp_eta = 0;                              // EXP: fixed rate (<= 0: sqrt(log |G| / N))
  std::vector<int> md_exponents{-2, -1, 0, 2, 4};  // MD: eta_k = 2^k log N
  double md_shift = -1;                            // MD: KL shift (< 0: 1 / (4 |G| + 1))
};

class SelectionPolicy {
 public:
  explicit SelectionPolicy(SelectionSettings settings = {});

  SelectionKind kind() const { return settings_.kind; }
  CostKind cost_kind() const {
    return settings_.kind == SelectionKind::Proj ? CostKind::distance : CostKind::objective;
  }
  // A fresh distribution over num_goals (>= 1) goals; initial_costs (may be null) start Fixed.
  void reset(int num_goals, int horizon, const Eigen::VectorXd* initial_costs = nullptr);
  // A new goal joins (C-Space ISF's refined copy): it gets the mode's mass, then p is renormalized.
  void add_goal();
  // p_{i+1} from the normalized cost vector c_{i+1} (finite, one entry per goal).
  const Eigen::VectorXd& update(const Eigen::VectorXd& costs);
  int select() const;  // the mode of p; ties: the lowest index
  const Eigen::VectorXd& p() const { return p_; }
  int size() const { return static_cast<int>(p_.size()); }
  double regret() const;  // eq. 9 over the updates so far

 private:
  Eigen::VectorXd next(const Eigen::VectorXd& c);
  Eigen::VectorXd md_next(const Eigen::VectorXd& c);
  void require_reset() const;

  SelectionSettings settings_;
  int horizon_ = 1;
  Eigen::VectorXd p_;
  std::vector<Eigen::VectorXd> costs_, played_;  // per update (grown with the goal set)
  Eigen::MatrixXd experts_;                      // MD: one distribution per row
  Eigen::VectorXd weights_;                      // MD: expert weights
};

// numpy's sum of a contiguous double array (its pairwise summation), for matching reductions.
double numpy_sum(const double* a, long n);
// Rows of argmin_p <eta c, p> + KL(p + shift || P_row + shift) over the simplex (selection.py's
// shifted_kl_step); scaled_costs holds eta_k c per row.
Eigen::MatrixXd shifted_kl_step(const Eigen::MatrixXd& P, const Eigen::MatrixXd& scaled_costs, double shift);

}  // namespace pickplan::omg
