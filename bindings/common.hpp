#pragma once
// Shared helpers for the pickplan._core bindings: numpy views with shape checks.
#include <limits>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <pybind11/eigen.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "pickplan/core/errors.hpp"
#include "pickplan/core/robot.hpp"

namespace py = pybind11;

namespace pickplan::bind {

using core::cleaned_rigid;
using core::Robot;
using core::Transform;

using Array = py::array_t<double, py::array::c_style | py::array::forcecast>;
using IntArray = py::array_t<int, py::array::c_style | py::array::forcecast>;

inline std::string shape_str(const py::array& a) {
  std::ostringstream s;
  s << "(";
  for (py::ssize_t i = 0; i < a.ndim(); ++i) s << (i ? ", " : "") << a.shape(i);
  s << (a.ndim() == 1 ? ",)" : ")");
  return s.str();
}

// Checks a's shape against `shape` (-1 = any size); throws ValueError "what: expected shape (N, 3), got (...)".
inline void require_shape(const char* what, const py::array& a, std::vector<py::ssize_t> shape,
                          const char* expected_desc) {
  bool ok = a.ndim() == static_cast<py::ssize_t>(shape.size());
  for (size_t i = 0; ok && i < shape.size(); ++i) ok = shape[i] < 0 || a.shape(i) == shape[i];
  if (!ok)
    throw std::invalid_argument(std::string(what) + ": expected shape " + expected_desc + ", got " + shape_str(a));
}

inline void require_finite_array(const char* what, const Array& a) {
  core::require_finite(what, a.data(), static_cast<long>(a.size()));
}

// A configuration vector of the robot's size, finite.
inline Array configuration(const Robot& robot, const Array& q, const char* what = "configuration") {
  if (q.ndim() != 1)
    throw std::invalid_argument(std::string(what) + ": expected a 1-D array of " + std::to_string(robot.dof()) +
                                " joint values, got shape " + shape_str(q));
  robot.check_configuration(q.data(), static_cast<long>(q.shape(0)));
  return q;
}

// A (B, dof) batch of finite configurations.
inline Array configurations(const Robot& robot, const Array& Q, const char* what = "configurations") {
  std::string desc = "(B, " + std::to_string(robot.dof()) + ")";
  require_shape(what, Q, {-1, robot.dof()}, desc.c_str());
  require_finite_array(what, Q);
  return Q;
}

inline Eigen::Matrix4d matrix4(const Array& a, const char* what) {
  require_shape(what, a, {4, 4}, "(4, 4)");
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) M(r, c) = a.at(r, c);
  return cleaned_rigid(what, M);  // the same tolerance as pickplan.core.poses
}

// An index into [0, size): Python ints of any size are compared before narrowing, so 2**32 + 3
// is out of range instead of wrapping to 3.
inline int index_arg(const char* what, const py::object& value, int size) {
  const long long i = value.cast<long long>();  // raises for ints past 64 bits
  if (i < 0 || i >= size)
    throw std::invalid_argument(std::string(what) + " " + std::to_string(i) + " out of range [0, " +
                                std::to_string(size) + ")");
  return static_cast<int>(i);
}

// An integer array of indices into [0, size), checked at full width before narrowing to int: a
// numpy int64 2**32 + 3 would otherwise wrap silently to 3. Returned C-contiguous as int32.
// Mesh faces pass kMaxIndex: the core names a face's vertex out of range itself.
constexpr py::ssize_t kMaxIndex = std::numeric_limits<int>::max();
inline IntArray index_array(const char* what, const py::handle& value, py::ssize_t size) {
  py::array a = py::array::ensure(value);
  if (!a) throw std::invalid_argument(std::string(what) + ": expected an array of integer indices");
  const char kind = a.dtype().kind();
  if (a.size() > 0 && kind != 'i' && kind != 'u')
    throw std::invalid_argument(std::string(what) + ": expected integer indices, got dtype " +
                                py::str(a.dtype()).cast<std::string>());
  auto bad = [&](const std::string& v, py::ssize_t j) {
    return std::invalid_argument(std::string(what) + ": entry " + std::to_string(j) + " = " + v + " out of range [0, " +
                                 std::to_string(size) + ")");
  };
  if (kind == 'u') {  // uint64 past 2**63 must not turn negative before the check
    auto u = py::array_t < unsigned long long, py::array::c_style | py::array::forcecast > ::ensure(a);
    for (py::ssize_t j = 0; j < u.size(); ++j)
      if (u.data()[j] >= static_cast<unsigned long long>(size)) throw bad(std::to_string(u.data()[j]), j);
  } else if (a.size() > 0) {
    auto w = py::array_t < long long, py::array::c_style | py::array::forcecast > ::ensure(a);
    for (py::ssize_t j = 0; j < w.size(); ++j)
      if (w.data()[j] < 0 || w.data()[j] >= size) throw bad(std::to_string(w.data()[j]), j);
  }
  return IntArray::ensure(a);  // every value fits now, so the cast to int is exact
}

// A rigid (4, 4) pose.
inline Transform pose_arg(const Array& T, const char* what) { return Transform::from_matrix(matrix4(T, what)); }

// An (N, 4, 4) array of rigid poses.
inline std::vector<Transform> poses_arg(const Array& P, const char* what) {
  require_shape(what, P, {-1, 4, 4}, "(N, 4, 4)");
  require_finite_array(what, P);
  std::vector<Transform> out;
  for (py::ssize_t i = 0; i < P.shape(0); ++i) {
    Eigen::Matrix4d M = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(P.data() + 16 * i);
    out.push_back(
        Transform::from_matrix(cleaned_rigid((std::string(what) + " [" + std::to_string(i) + "]").c_str(), M)));
  }
  return out;
}

inline void write_matrix4(const Transform& T, double* out) {
  Eigen::Map<Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> M(out);
  M = T.matrix();
}

// A link given by index or by name.
inline int link_arg(const Robot& robot, const py::object& link) {
  if (py::isinstance<py::str>(link)) return robot.link_index(link.cast<std::string>());
  if (py::isinstance<py::int_>(link)) return index_arg("link index", link, robot.num_links());
  throw std::invalid_argument("link: expected a link name (str) or index (int)");
}

}  // namespace pickplan::bind
