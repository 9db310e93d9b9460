#pragma once
// Tiny benchmark harness for pickplan-bench: fixed seeded inputs, median / worst per case.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <functional>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "pickplan/core/robot.hpp"

namespace pickplan::bench {

struct Options {
  std::string urdf;     // Panda URDF
  std::string ycb_dir;  // optional real-object folder
  int samples = 200;    // timed samples per case
  std::map<std::string, std::string> extra;
};

struct Stats {
  double median = 0, worst = 0, mean = 0;
};

inline Stats summarize(std::vector<double> v) {
  Stats s;
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.median = v[v.size() / 2];
  s.worst = v.back();
  for (double x : v) s.mean += x;
  s.mean /= v.size();
  return s;
}

// Times `fn(i)` for i in [0, samples): each sample runs `reps` calls; returns per-call seconds.
inline std::vector<double> time_samples(int samples, int reps, const std::function<void(int)>& fn) {
  std::vector<double> out;
  out.reserve(samples);
  for (int i = 0; i < samples; ++i) {
    auto t0 = std::chrono::steady_clock::now();
    for (int r = 0; r < reps; ++r) fn(i);
    auto t1 = std::chrono::steady_clock::now();
    out.push_back(std::chrono::duration<double>(t1 - t0).count() / reps);
  }
  return out;
}

inline void report(const char* name, const Stats& s, const char* unit_note = "") {
  auto fmt = [](double sec) {
    static char buf[4][32];
    static int k = 0;
    char* b = buf[k++ % 4];
    if (sec < 1e-6)
      std::snprintf(b, 32, "%.1f ns", sec * 1e9);
    else if (sec < 1e-3)
      std::snprintf(b, 32, "%.2f us", sec * 1e6);
    else if (sec < 1)
      std::snprintf(b, 32, "%.2f ms", sec * 1e3);
    else
      std::snprintf(b, 32, "%.3f s", sec);
    return b;
  };
  std::printf("%-48s median %12s   worst %12s   mean %12s %s\n", name, fmt(s.median), fmt(s.worst), fmt(s.mean),
              unit_note);
  std::fflush(stdout);
}

// n seeded configurations uniform within the joint limits (continuous joints in [-pi, pi]).
inline std::vector<Eigen::VectorXd> random_configurations(const core::Robot& robot, int n, unsigned seed) {
  std::mt19937 rng(seed);
  std::vector<Eigen::VectorXd> qs;
  for (int i = 0; i < n; ++i) {
    Eigen::VectorXd q(robot.dof());
    for (int j = 0; j < robot.dof(); ++j) {
      const double lo = std::isfinite(robot.lower_limits()[j]) ? robot.lower_limits()[j] : -M_PI;
      const double hi = std::isfinite(robot.upper_limits()[j]) ? robot.upper_limits()[j] : M_PI;
      q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
    }
    qs.push_back(q);
  }
  return qs;
}

// Benchmark sections register themselves; main runs those selected with --only.
using Section = std::function<void(const Options&)>;
std::map<std::string, Section>& sections();
struct Register {
  Register(const std::string& name, Section fn) { sections()[name] = std::move(fn); }
};

}  // namespace pickplan::bench
