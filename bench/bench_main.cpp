// pickplan-bench: timings of the native core on fixed, seeded inputs.
//   pickplan-bench [--urdf PANDA_URDF] [--ycb DIR] [--only SECTION[,SECTION]] [--samples N]
#include <cstdlib>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "bench_common.hpp"

namespace fs = std::filesystem;

namespace pickplan::bench {
std::map<std::string, Section>& sections() {
  static std::map<std::string, Section> s;
  return s;
}
}  // namespace pickplan::bench

namespace {

// Finds pybullet_data's Panda next to this executable's virtual environment (venv/bin/..)
// or its site-packages (the wheel's layout).
std::string find_panda_urdf(const char* argv0) {
  if (const char* env = std::getenv("PICKPLAN_PANDA_URDF")) return env;
  std::error_code ec;
  fs::path exe = fs::canonical("/proc/self/exe", ec);
  if (ec) exe = fs::absolute(argv0);
  // Installed from the wheel, auditwheel moves this program to site-packages/pickplan.scripts/.
  fs::path beside = exe.parent_path().parent_path() / "pybullet_data" / "franka_panda" / "panda.urdf";
  if (fs::is_regular_file(beside, ec)) return beside.string();
  for (fs::path venv : {exe.parent_path().parent_path(), fs::current_path() / ".venv"}) {
    fs::path lib = venv / "lib";
    if (!fs::is_directory(lib, ec)) continue;
    for (const auto& py : fs::directory_iterator(lib, ec)) {
      fs::path cand = py.path() / "site-packages" / "pybullet_data" / "franka_panda" / "panda.urdf";
      if (fs::is_regular_file(cand, ec)) return cand.string();
    }
  }
  return "";
}

}  // namespace

int main(int argc, char** argv) {
  using namespace pickplan::bench;
  Options opt;
  std::string only;
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::cerr << "pickplan-bench: " << a << " needs a value\n";
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--urdf")
      opt.urdf = next();
    else if (a == "--ycb")
      opt.ycb_dir = next();
    else if (a == "--only")
      only = next();
    else if (a == "--samples")
      opt.samples = std::atoi(next().c_str());
    else if (a.rfind("--", 0) == 0 && a.find('=') != std::string::npos)
      opt.extra[a.substr(2, a.find('=') - 2)] = a.substr(a.find('=') + 1);
    else if (a == "-h" || a == "--help") {
      std::cout
          << "usage: pickplan-bench [--urdf PANDA_URDF] [--ycb DIR] [--only SECTION,...] [--samples N]\nsections:";
      for (const auto& [name, fn] : sections()) std::cout << " " << name;
      std::cout << "\n";
      return 0;
    } else {
      std::cerr << "pickplan-bench: unknown argument '" << a << "' (try --help)\n";
      return 2;
    }
  }
  if (opt.urdf.empty()) opt.urdf = find_panda_urdf(argv[0]);
  if (opt.urdf.empty() || !fs::is_regular_file(opt.urdf)) {
    std::cerr << "pickplan-bench: Panda URDF not found; pass --urdf PATH (pybullet_data/franka_panda/panda.urdf) "
                 "or set PICKPLAN_PANDA_URDF\n";
    return 2;
  }
  if (opt.ycb_dir.empty()) {
    if (const char* env = std::getenv("PICKPLAN_YCB_DIR")) opt.ycb_dir = env;
  }
  std::cout << "pickplan-bench  model: " << opt.urdf << "\n";
  std::vector<std::string> selected;
  if (only.empty()) {
    for (const auto& [name, fn] : sections()) selected.push_back(name);
  } else {
    std::stringstream ss(only);
    for (std::string s; std::getline(ss, s, ',');) selected.push_back(s);
  }
  for (const auto& name : selected) {
    auto it = sections().find(name);
    if (it == sections().end()) {
      std::cerr << "pickplan-bench: unknown section '" << name << "'\n";
      return 2;
    }
    std::cout << "\n[" << name << "]\n";
    try {
      it->second(opt);
    } catch (const std::exception& e) {
      std::cerr << "pickplan-bench: section '" << name << "' failed: " << e.what() << "\n";
      return 1;
    }
  }
  return 0;
}
