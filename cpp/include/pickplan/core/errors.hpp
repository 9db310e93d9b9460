#pragma once
// Error types of the native core. Misuse throws; "no solution" is a status in a result.
// std::invalid_argument maps to Python ValueError, FileNotFound to FileNotFoundError.
#include <stdexcept>
#include <string>

namespace pickplan::core {

class FileNotFound : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Throws std::invalid_argument("<what>: expected N <unit>, got M").
void require_size(const char* what, long expected, long got, const char* unit = "values");
// Throws std::invalid_argument when any of n values is NaN or infinite.
void require_finite(const char* what, const double* values, long n);

}  // namespace pickplan::core
