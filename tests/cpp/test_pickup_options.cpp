// Pick-up NLP option enums: every value's text form parses back to it (the spellings Ipopt and the
// JSON files use), and a misspelt option is an error that lists the valid ones.
#include <set>
#include <stdexcept>
#include <string>

#include <gtest/gtest.h>

#include "pickplan/pickup/options.hpp"

using namespace pickplan::pickup;

TEST(PickupOptions, TextFormsRoundTrip) {
  for (auto v : {HessianMode::exact, HessianMode::limited_memory}) EXPECT_EQ(parse_hessian_mode(to_string(v)), v);
  for (auto v : {CoefficientBasis::bernstein, CoefficientBasis::monomial})
    EXPECT_EQ(parse_coefficient_basis(to_string(v)), v);
  for (auto v : {MuStrategy::monotone, MuStrategy::adaptive}) EXPECT_EQ(parse_mu_strategy(to_string(v)), v);
  for (auto v : {RateRows::hull, RateRows::sampled}) EXPECT_EQ(parse_rate_rows(to_string(v)), v);
  std::set<std::string> statuses;  // one text form per status (results are written, never read back)
  for (int i = 0; i <= static_cast<int>(SolveStatus::time_limit); ++i)
    statuses.insert(to_string(static_cast<SolveStatus>(i)));
  EXPECT_EQ(statuses.size(), static_cast<size_t>(SolveStatus::time_limit) + 1);
  // Ipopt's own spelling of its option value, not the C++ identifier.
  EXPECT_STREQ(to_string(HessianMode::limited_memory), "limited-memory");
}

TEST(PickupOptions, MisspeltOptionListsTheValidOnes) {
  try {
    parse_hessian_mode("limited_memory");
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'limited_memory'"), std::string::npos) << what;
    EXPECT_NE(what.find("'exact', 'limited-memory'"), std::string::npos) << what;
  }
  EXPECT_THROW(parse_rate_rows("Hull"), std::invalid_argument);
  EXPECT_THROW(parse_mu_strategy(""), std::invalid_argument);
  EXPECT_THROW(parse_coefficient_basis("chebyshev"), std::invalid_argument);
}
