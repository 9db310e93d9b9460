#include "pickplan/core/errors.hpp"

#include <cmath>
#include <sstream>

namespace pickplan::core {

void require_size(const char* what, long expected, long got, const char* unit) {
  if (expected == got) return;
  std::ostringstream msg;
  msg << what << ": expected " << expected << " " << unit << ", got " << got;
  throw std::invalid_argument(msg.str());
}

void require_finite(const char* what, const double* values, long n) {
  for (long i = 0; i < n; ++i) {
    if (!std::isfinite(values[i])) {
      std::ostringstream msg;
      msg << what << ": value " << i << " is " << values[i] << " (NaN or infinite values are not allowed)";
      throw std::invalid_argument(msg.str());
    }
  }
}

}  // namespace pickplan::core
