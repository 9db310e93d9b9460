// The single extension module pickplan._core; one init function per area.
#include "common.hpp"

namespace pickplan::bind {
void init_robot(py::module_& m);
void init_sdf(py::module_& m);
void init_chomp(py::module_& m);
void init_collision(py::module_& m);
void init_ik(py::module_& m);
void init_goal_set(py::module_& m);
void init_isf(py::module_& m);
void init_omg_loop(py::module_& m);
void init_pickup_nlp(py::module_& m);
void init_perception(py::module_& m);
void init_point_sections(py::module_& m);
void init_primitives(py::module_& m);
void init_rrt_connect(py::module_& m);
}  // namespace pickplan::bind

PYBIND11_MODULE(_core, m) {
  m.doc() = "pickplan native core (private: use the pickplan Python modules)";
  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const pickplan::core::FileNotFound& e) {
      PyErr_SetString(PyExc_FileNotFoundError, e.what());
    }
  });
  m.attr("RIGID_CLEAN_TOLERANCE") = pickplan::core::kRigidCleanTolerance;
  pickplan::bind::init_robot(m);
  pickplan::bind::init_sdf(m);
  pickplan::bind::init_chomp(m);
  pickplan::bind::init_collision(m);
  pickplan::bind::init_ik(m);
  pickplan::bind::init_goal_set(m);
  pickplan::bind::init_isf(m);
  pickplan::bind::init_omg_loop(m);
  pickplan::bind::init_pickup_nlp(m);
  pickplan::bind::init_perception(m);
  pickplan::bind::init_point_sections(m);
  pickplan::bind::init_primitives(m);  // extends SceneSdf and CollisionShape: after both
  pickplan::bind::init_rrt_connect(m);
}
