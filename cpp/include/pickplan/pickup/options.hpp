#pragma once
// Option values of the pick-up NLP (PickupSettings) as enums. Their text forms are Ipopt's
// spellings where Ipopt takes them, and the values Python and the JSON files use.
#include <ostream>
#include <string>

namespace pickplan::pickup {

enum class HessianMode { exact, limited_memory };     // eval_hessian | Ipopt's L-BFGS ("limited-memory")
enum class CoefficientBasis { bernstein, monomial };  // Ipopt's coefficient variables (results: monomial)
enum class MuStrategy { monotone, adaptive };         // Ipopt's barrier update
enum class RateRows { hull, sampled };                // rate limits on Bernstein points | at the samples

// How a stage (or the whole solve) ended. The first ones are Ipopt's return codes, shortened;
// bounded: converged, but T is not below the best known (a search run stopped early);
// violation_between_samples / constraint_violation: converged, but the dense check between the
// samples or the full row set still fails after the active-set rounds; not_run: never attempted;
// time_limit: the wall-clock budget (PickupSettings::time_limit) ran out (the result holds the best
// feasible solution found before, if any: PickupResult::success).
enum class SolveStatus {
  not_run,
  solved,
  solved_acceptable,
  infeasible,
  diverging,
  max_iterations,
  max_cpu_time,
  restoration_failed,
  step_too_small,
  invalid_number,
  solver_error,
  bounded,
  violation_between_samples,
  constraint_violation,
  time_limit
};

const char* to_string(HessianMode mode);
const char* to_string(CoefficientBasis basis);
const char* to_string(MuStrategy strategy);
const char* to_string(RateRows rows);
const char* to_string(SolveStatus status);

// The option named by its text form; std::invalid_argument listing the valid ones otherwise.
HessianMode parse_hessian_mode(const std::string& text);
CoefficientBasis parse_coefficient_basis(const std::string& text);
MuStrategy parse_mu_strategy(const std::string& text);
RateRows parse_rate_rows(const std::string& text);
inline std::ostream& operator<<(std::ostream& os, SolveStatus status) { return os << to_string(status); }

}  // namespace pickplan::pickup
