// The checker's batch queries: rows of configurations split over threads, a workspace each.
#include <algorithm>
#include <thread>
#include <vector>

#include "pickplan/geometry/collision.hpp"

namespace pickplan::geometry {

namespace {

template <class Fn>
void parallel_rows(long B, int threads, const Fn& fn) {
  if (threads <= 0) threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  threads = static_cast<int>(std::min<long>(threads, std::max(1L, B)));
  if (threads == 1) {
    fn(0L, B);
    return;
  }
  std::vector<std::thread> pool;
  const long chunk = (B + threads - 1) / threads;
  for (int t = 0; t < threads; ++t) {
    const long lo = t * chunk, hi = std::min(B, lo + chunk);
    if (lo < hi) pool.emplace_back([&fn, lo, hi] { fn(lo, hi); });
  }
  for (auto& th : pool) th.join();
}

}  // namespace

void CollisionChecker::in_collision_batch(const double* Q, long B, bool* out, int threads) const {
  const int d = robot_.dof();
  for (long b = 0; b < B; ++b) check_q(Q + b * d);  // validate before any thread starts
  parallel_rows(B, threads, [&](long lo, long hi) {
    CollisionWorkspace ws(*this);
    for (long b = lo; b < hi; ++b) out[b] = in_collision(Q + b * d, ws);
  });
}

void CollisionChecker::min_distance_batch(const double* Q, long B, double* out, int threads) const {
  const int d = robot_.dof();
  for (long b = 0; b < B; ++b) check_q(Q + b * d);
  parallel_rows(B, threads, [&](long lo, long hi) {
    CollisionWorkspace ws(*this);
    for (long b = lo; b < hi; ++b) out[b] = min_distance(Q + b * d, ws);
  });
}

}  // namespace pickplan::geometry
