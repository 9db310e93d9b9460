// The wall-clock budget of one native pick-up solve (PickupSettings::time_limit), shared by the
// stages and active-set rounds of solve_successive and solve_single_shot (solve.cpp).
#pragma once

#include <algorithm>
#include <chrono>

#include "pickplan/pickup/nlp.hpp"

namespace pickplan::pickup {
namespace detail {

// The wall-clock limit of solve_successive's and solve_single_shot's runs (PickupSettings::time_limit).
struct RunLimits {
  // Wall-clock deadline (PickupSettings::time_limit; max: none): no run starts when it is nearer
  // than the quickest iteration so far plus `between`, and each run is told the time left less `between`.
  std::chrono::steady_clock::time_point deadline = std::chrono::steady_clock::time_point::max();
  // The shortest mean Ipopt iteration of a run of this call that the deadline did not cut (s): a
  // run started with less time left would end past the deadline (its start-up and first iteration
  // take about that long). The whole shortest run was the measure before: a stage that ended at its
  // iteration limit then stopped the call with a third of its budget left (5 behind and 2 cluttered
  // budgeted runs of 100 ended before 1.85 s of 2). Mutable: statistics of the call, kept where its
  // runs are counted.
  mutable double quickest_iteration = 0.0;
  // The longest stretch of work between an Ipopt run's end and the next run's start (the
  // full-stage and dense checks of a round, the next stage's IK or timing seed; s): each run is told
  // the time left less this, so the same work after the last run still ends by the deadline (in
  // clutter the dense check after a run that converged near the deadline ended the call 3-8 ms past it).
  mutable double between = 0.0;
  mutable std::chrono::steady_clock::time_point last_end{};
  bool limited() const { return deadline != std::chrono::steady_clock::time_point::max(); }
  bool expired() const {
    return limited() && std::chrono::steady_clock::now() + seconds(quickest_iteration + between) >= deadline;
  }
  // A run starts now: the work since the last one ended counts towards `between`.
  void start() const {
    if (last_end != std::chrono::steady_clock::time_point{})
      between = std::max(between, std::chrono::duration<double>(std::chrono::steady_clock::now() - last_end).count());
  }
  void count(double run_seconds, int iterations, bool cut) const {
    const double step = run_seconds / std::max(1, iterations);
    if (!cut) quickest_iteration = quickest_iteration > 0.0 ? std::min(quickest_iteration, step) : step;
    last_end = std::chrono::steady_clock::now();
  }
  static std::chrono::steady_clock::duration seconds(double s) {
    return std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(s));
  }
  double seconds_left() const {
    if (!limited()) return 0.0;  // 0: no limit
    return std::max(1e-3, std::chrono::duration<double>(deadline - std::chrono::steady_clock::now()).count() - between);
  }
};

// The deadline of a call that starts now with settings.time_limit (none when it is 0).
inline std::chrono::steady_clock::time_point deadline_of(const PickupSettings& st) {
  if (!(st.time_limit > 0)) return std::chrono::steady_clock::time_point::max();
  return std::chrono::steady_clock::now() +
         std::chrono::duration_cast<std::chrono::steady_clock::duration>(std::chrono::duration<double>(st.time_limit));
}

}  // namespace detail
}  // namespace pickplan::pickup
