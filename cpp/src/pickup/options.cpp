#include "pickplan/pickup/options.hpp"

#include <stdexcept>
#include <utility>

namespace pickplan {

namespace {

template <class E>
using Names = std::pair<E, const char*>;

constexpr Names<HessianMode> kHessian[] = {{HessianMode::exact, "exact"},
                                           {HessianMode::limited_memory, "limited-memory"}};
constexpr Names<CoefficientBasis> kBasis[] = {{CoefficientBasis::bernstein, "bernstein"},
                                              {CoefficientBasis::monomial, "monomial"}};
constexpr Names<MuStrategy> kMu[] = {{MuStrategy::monotone, "monotone"}, {MuStrategy::adaptive, "adaptive"}};
constexpr Names<RateRows> kRates[] = {{RateRows::hull, "hull"}, {RateRows::sampled, "sampled"}};

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

HessianMode parse_hessian_mode(const std::string& text) { return parse(kHessian, text, "hessian"); }
CoefficientBasis parse_coefficient_basis(const std::string& text) { return parse(kBasis, text, "basis"); }
MuStrategy parse_mu_strategy(const std::string& text) { return parse(kMu, text, "mu_strategy"); }
RateRows parse_rate_rows(const std::string& text) { return parse(kRates, text, "rate_rows"); }

}  // namespace pickplan
