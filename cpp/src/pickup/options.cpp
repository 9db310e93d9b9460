#include "pickplan/pickup/options.hpp"

#include <stdexcept>
#include <utility>

namespace pickplan::pickup {

namespace {

template <class E>
using Names = std::pair<E, const char*>;

constexpr Names<HessianMode> kHessian[] = {{HessianMode::exact, "exact"},
                                           {HessianMode::limited_memory, "limited-memory"}};
constexpr Names<CoefficientBasis> kBasis[] = {{CoefficientBasis::bernstein, "bernstein"},
                                              {CoefficientBasis::monomial, "monomial"}};
constexpr Names<MuStrategy> kMu[] = {{MuStrategy::monotone, "monotone"}, {MuStrategy::adaptive, "adaptive"}};
constexpr Names<RateRows> kRates[] = {{RateRows::hull, "hull"}, {RateRows::sampled, "sampled"}};
constexpr Names<SolveStatus> kStatus[] = {{SolveStatus::not_run, "not_run"},
                                          {SolveStatus::solved, "solved"},
                                          {SolveStatus::solved_acceptable, "solved_acceptable"},
                                          {SolveStatus::infeasible, "infeasible"},
                                          {SolveStatus::diverging, "diverging"},
                                          {SolveStatus::max_iterations, "max_iterations"},
                                          {SolveStatus::max_cpu_time, "max_cpu_time"},
                                          {SolveStatus::restoration_failed, "restoration_failed"},
                                          {SolveStatus::step_too_small, "step_too_small"},
                                          {SolveStatus::invalid_number, "invalid_number"},
                                          {SolveStatus::solver_error, "solver_error"},
                                          {SolveStatus::bounded, "bounded"},
                                          {SolveStatus::violation_between_samples, "violation_between_samples"},
                                          {SolveStatus::constraint_violation, "constraint_violation"},
                                          {SolveStatus::time_limit, "time_limit"}};

template <class E, std::size_t N>
const char* name_of(const Names<E> (&names)[N], E value) {
  for (const auto& [v, text] : names)
    if (v == value) return text;
  throw std::invalid_argument("invalid option value " + std::to_string(static_cast<int>(value)));
}

template <class E, std::size_t N>
E parse(const Names<E> (&names)[N], const std::string& text, const char* what) {
  std::string valid;
  for (const auto& [v, name] : names) {
    if (text == name) return v;
    valid += std::string(valid.empty() ? "" : ", ") + "'" + name + "'";
  }
  throw std::invalid_argument(std::string("unknown ") + what + " '" + text + "'; valid: " + valid);
}

}  // namespace

const char* to_string(HessianMode mode) { return name_of(kHessian, mode); }
const char* to_string(CoefficientBasis basis) { return name_of(kBasis, basis); }
const char* to_string(MuStrategy strategy) { return name_of(kMu, strategy); }
const char* to_string(RateRows rows) { return name_of(kRates, rows); }
const char* to_string(SolveStatus status) { return name_of(kStatus, status); }

HessianMode parse_hessian_mode(const std::string& text) { return parse(kHessian, text, "hessian"); }
CoefficientBasis parse_coefficient_basis(const std::string& text) { return parse(kBasis, text, "basis"); }
MuStrategy parse_mu_strategy(const std::string& text) { return parse(kMu, text, "mu_strategy"); }
RateRows parse_rate_rows(const std::string& text) { return parse(kRates, text, "rate_rows"); }

}  // namespace pickplan::pickup
