// Pick-up on the move (Thakar et al.): the five stages of successive refinement per test case,
// and the single-shot baseline. Options: --mobile_urdf=PATH --cases=1,2,... --m=8 --shots=1
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <sstream>

#include "bench_common.hpp"
#include "pickplan/pickup/cases.hpp"

using namespace pickplan::core;
using namespace pickplan::pickup;

namespace pickplan::bench {
namespace {

std::string find_mobile_urdf(const Options& opt) {
  auto it = opt.extra.find("mobile_urdf");
  if (it != opt.extra.end()) return it->second;
  if (const char* env = std::getenv("PICKPLAN_MOBILE_UR5_URDF")) return env;
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::path exe = fs::canonical("/proc/self/exe", ec);
  for (fs::path dir = exe.parent_path(); !dir.empty() && dir != dir.root_path(); dir = dir.parent_path()) {
    if (fs::is_regular_file(dir / "assets" / "mobile_ur5.urdf", ec))
      return (dir / "assets" / "mobile_ur5.urdf").string();
    fs::path lib = dir / "lib";
    if (fs::is_directory(lib, ec))
      for (const auto& py : fs::directory_iterator(lib, ec)) {
        fs::path c = py.path() / "site-packages" / "pickplan" / "assets" / "mobile_ur5.urdf";
        if (fs::is_regular_file(c, ec)) return c.string();
      }
  }
  return "assets/mobile_ur5.urdf";
}

void bench_pickup(const Options& opt) {
  Robot robot = Robot::from_urdf_file(find_mobile_urdf(opt));
  PickupSettings st;
  if (opt.extra.count("m")) st.samples_per_interval = std::atoi(opt.extra.at("m").c_str());
  if (opt.extra.count("print")) st.print_level = std::atoi(opt.extra.at("print").c_str());
  if (opt.extra.count("max_iter")) st.max_iter = std::atoi(opt.extra.at("max_iter").c_str());
  if (opt.extra.count("mu")) st.mu_strategy = parse_mu_strategy(opt.extra.at("mu"));
  if (opt.extra.count("hessian")) st.hessian = parse_hessian_mode(opt.extra.at("hessian"));
  if (opt.extra.count("basis")) st.basis = parse_coefficient_basis(opt.extra.at("basis"));
  if (opt.extra.count("active")) st.active_set = std::atoi(opt.extra.at("active").c_str()) != 0;
  if (opt.extra.count("dense")) st.dense_subdivisions = std::atoi(opt.extra.at("dense").c_str());
  if (opt.extra.count("jwin")) st.active_joint_window = std::atof(opt.extra.at("jwin").c_str());
  if (opt.extra.count("rates")) st.rate_rows = parse_rate_rows(opt.extra.at("rates"));
  if (opt.extra.count("hulldeg")) st.rate_hull_degree = std::atoi(opt.extra.at("hulldeg").c_str());
  if (opt.extra.count("cwin")) st.active_collision_window = std::atof(opt.extra.at("cwin").c_str());
  if (opt.extra.count("tseed")) st.timing_seed = std::atoi(opt.extra.at("tseed").c_str()) != 0;
  if (opt.extra.count("tfrac")) st.timing_fraction = std::atof(opt.extra.at("tfrac").c_str());
  if (opt.extra.count("direct")) st.direct_track = std::atoi(opt.extra.at("direct").c_str()) != 0;
  if (opt.extra.count("armseeds")) st.arm_seeds = std::atoi(opt.extra.at("armseeds").c_str());
  if (opt.extra.count("direct_iter")) st.direct_max_iter = std::atoi(opt.extra.at("direct_iter").c_str());
  // --synth=A: the Python stand-in surface synthetic_rho with slope A (medium sigma: 0.22).
  RhoPoly rho = example_rho();
  if (opt.extra.count("synth")) {
    const double a = std::atof(opt.extra.at("synth").c_str());
    rho.coeffs.resize(4, 3);
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 3; ++j) rho.coeffs(i, j) = std::clamp(1.0 - a * (i / 3.0) * (1.0 - 0.3 * j / 2.0), 0.0, 1.0);
  }
  if (opt.extra.count("warm")) st.warm_start_stages = std::atoi(opt.extra.at("warm").c_str()) != 0;
  if (opt.extra.count("push")) st.warm_start_push = std::atof(opt.extra.at("push").c_str());
  if (opt.extra.count("mu_resolve")) st.mu_resolve = std::atof(opt.extra.at("mu_resolve").c_str());
  if (opt.extra.count("mu_init")) st.mu_init = std::atof(opt.extra.at("mu_init").c_str());
  for (const auto& [k, v] : opt.extra)
    if (k.rfind("ipopt.", 0) == 0) st.ipopt_options.push_back({k.substr(6), v});
  const int shots = opt.extra.count("shots") ? std::atoi(opt.extra.at("shots").c_str()) : 1;
  std::vector<int> cases = {1, 2, 3, 4, 5, 6};
  if (opt.extra.count("cases")) {
    cases.clear();
    std::stringstream ss(opt.extra.at("cases"));
    for (std::string tok; std::getline(ss, tok, ',');) cases.push_back(std::atoi(tok.c_str()));
  }
  std::printf("pick-up NLP: m = %d samples per interval, %s Hessian, MUMPS\n", st.samples_per_interval,
              to_string(st.hessian));
  {
    PickupProblem pb = paper_case(robot, 1, example_rho());
    PickupConstraints all(robot, pb, st, 0);
    Eigen::VectorXd x = heuristic_seed(robot, pb, st);
    std::vector<double> g(all.num_constraints()), jv(all.num_nonzeros());
    std::printf("all-constraint NLP: %d variables, %d constraints, %d Jacobian nonzeros\n", all.num_vars(),
                all.num_constraints(), all.num_nonzeros());
    report("constraints g(x), all stages' rows",
           summarize(time_samples(50, 5, [&](int) { all.eval_g(x.data(), g.data()); })));
    report("constraint Jacobian, all stages' rows",
           summarize(time_samples(50, 5, [&](int) { all.eval_jac(x.data(), jv.data()); })));
  }
  if (opt.extra.count("diag")) {  // worst-violated rows of the heuristic seed, per stage
    PickupProblem pb = paper_case(robot, std::atoi(opt.extra.at("diag").c_str()), example_rho());
    Eigen::VectorXd x = heuristic_seed(robot, pb, st);
    for (int stage = 1; stage <= 5; ++stage) {
      PickupConstraints c(robot, pb, st, stage);
      Eigen::VectorXd xl, xu, gl, gu, g(c.num_constraints());
      c.bounds(xl, xu, gl, gu);
      c.eval_g(x.data(), g.data());
      auto names = c.row_names();
      std::vector<std::pair<double, int>> v;
      for (int r = 0; r < c.num_constraints(); ++r) v.push_back({std::max(gl[r] - g[r], g[r] - gu[r]), r});
      std::sort(v.rbegin(), v.rend());
      std::printf("seed, stage %d rows violated most:", stage);
      for (int k = 0; k < 6 && k < (int)v.size(); ++k) std::printf(" %s %.3g;", names[v[k].second].c_str(), v[k].first);
      std::printf("\n");
    }
  }
  // --dumpq=1: the arm at T2 and each arm joint's range over [0, T] (to tell local optima apart).
  const bool dumpq = opt.extra.count("dumpq") && std::atoi(opt.extra.at("dumpq").c_str()) != 0;
  auto dump = [&](const char* what, const PickupResult& r) {
    if (!dumpq || r.x.size() == 0) return;
    Eigen::VectorXd q(robot.dof());
    r.traj.eval(r.x.data(), r.T2, q.data(), nullptr, nullptr);
    std::printf("   %s q(T2):", what);
    for (int i = 0; i < robot.dof(); ++i) std::printf(" %.2f", q[i]);
    Eigen::VectorXd lo = Eigen::VectorXd::Constant(robot.dof(), 1e9), hi = -lo;
    for (int k = 0; k <= 400; ++k) {
      r.traj.eval(r.x.data(), r.T * k / 400.0, q.data(), nullptr, nullptr);
      lo = lo.cwiseMin(q);
      hi = hi.cwiseMax(q);
    }
    std::printf(" | range:");
    for (int i = 3; i < robot.dof(); ++i) std::printf(" [%.2f, %.2f]", lo[i], hi[i]);
    std::printf("\n");
  };
  std::vector<double> totals, cpu_totals;
  int seq_wins = 0, compared = 0;
  for (int c : cases) {
    PickupProblem pb = paper_case(robot, c, rho);
    PickupResult r = solve_successive(robot, pb, st);
    std::printf("case %d: %-12s total %.3f s (cpu %.3f s) |", c, to_string(r.status), r.total_seconds,
                r.total_cpu_seconds);
    for (const auto& s : r.stages)
      std::printf(" s%d %.3fs/%dit%s", s.stage, s.seconds, s.iterations,
                  s.rounds > 1 ? ("/" + std::to_string(s.rounds) + "r").c_str() : "");
    if (r.direct.stage == 0 && r.direct.status != SolveStatus::not_run)
      std::printf(" direct %.3fs/%dit (cpu %.3f s) %s T %.2f%s", r.direct.seconds, r.direct.iterations,
                  r.direct.cpu_seconds, to_string(r.direct.status), r.direct.objective,
                  r.direct_chosen ? " [chosen]" : "");
    if (r.arm_seeds_tried > 1) {
      std::printf("   arm seeds (cpu %.3f s not kept), T:", r.search_cpu_seconds);
      for (int k = 0; k < r.arm_seeds_tried; ++k)
        std::printf(" %.2f%s", r.arm_seed_T[k], k == r.arm_seed_chosen ? "*" : "");
    }
    std::printf("\n");
    totals.push_back(r.total_seconds);
    cpu_totals.push_back(r.total_cpu_seconds);
    if (r.stages_completed > 0) {
      PickupMetrics m = evaluate_pickup(robot, pb, r);
      std::printf(
          "   T %.2f s  T1 %.2f  T2 %.2f  Sg %.3f  Sc %.3f  rho %.4f | pose err %.2e m %.2e rad | NH mean %.2e m/s "
          "drift %.2e m"
          " | v err %.2e | clear %.3f | base %.2f m/s, grasp %.2f m/s, gripper %.2f m/s\n",
          r.T, r.T1, r.T2, r.S_g, r.S_c, m.success_probability, m.pose_error_position, m.pose_error_orientation,
          m.nonholonomic_mean, m.nonholonomic_drift, m.velocity_error_max, m.min_clearance, m.base_speed_max,
          m.base_speed_grasp_mean, m.gripper_speed_grasp_mean);
    }
    dump("sequential", r);
    double best_single = std::numeric_limits<double>::infinity();
    for (int k = 0; k < shots; ++k) {
      PickupSettings s1 = st;
      s1.seed = k;
      PickupResult b = solve_single_shot(robot, pb, s1);
      std::printf("   single-shot seed %d: %-12s %.3f s (cpu %.3f s) %d it, T %.2f\n", k, to_string(b.status),
                  b.total_seconds, b.total_cpu_seconds, b.stages[0].iterations, b.stages[0].objective);
      if (b.success) best_single = std::min(best_single, b.T);
      if (b.success) dump("single shot", b);
    }
    if (shots > 0 && r.success) {
      ++compared;
      seq_wins += r.T < best_single;
      std::printf("   sequential T %.2f s vs best solved single shot %s\n", r.T,
                  std::isfinite(best_single) ? std::to_string(best_single).c_str() : "(none solved)");
    }
  }
  report("successive refinement, all five stages (per case)", summarize(totals), "[target <= 1 s]");
  report("successive refinement, thread CPU time (per case)", summarize(cpu_totals), "[target <= 1 s]");
  if (compared) std::printf("sequential T below the best single shot in %d of %d cases\n", seq_wins, compared);
}

Register reg("pickup_nlp", bench_pickup);

}  // namespace
}  // namespace pickplan::bench
