#pragma once
// Option values of the pick-up NLP (PickupSettings) as enums. Their text forms are Ipopt's
// spellings where Ipopt takes them, and the values Python and the JSON files use.
#include <string>

namespace pickplan {

enum class HessianMode { exact, limited_memory };     // eval_hessian | Ipopt's L-BFGS ("limited-memory")
enum class CoefficientBasis { bernstein, monomial };  // Ipopt's coefficient variables (results: monomial)
enum class MuStrategy { monotone, adaptive };         // Ipopt's barrier update
enum class RateRows { hull, sampled };                // rate limits on Bernstein points | at the samples

const char* to_string(HessianMode mode);
const char* to_string(CoefficientBasis basis);
const char* to_string(MuStrategy strategy);
const char* to_string(RateRows rows);

// The option named by its text form; std::invalid_argument listing the valid ones otherwise.
HessianMode parse_hessian_mode(const std::string& text);
CoefficientBasis parse_coefficient_basis(const std::string& text);
MuStrategy parse_mu_strategy(const std::string& text);
RateRows parse_rate_rows(const std::string& text);

}  // namespace pickplan
