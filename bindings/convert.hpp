#pragma once
// Configurations and arrays crossing the binding, one way each: numpy in (shape and finiteness
// checked, copied into Eigen) and Eigen out (copied into a new numpy array).
#include <string>
#include <vector>

#include "common.hpp"
#include "pickplan/geometry/mesh.hpp"

namespace pickplan::bind {

// Row-major like numpy: Trajectory (omg/chomp.hpp) and the other n x dof matrices are this type.
using geometry::TriangleMesh;

using Rows = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// One configuration of the robot's size, finite.
inline Eigen::VectorXd configuration_vector(const Robot& robot, const Array& q, const char* what = "configuration") {
  const Array checked = configuration(robot, q, what);
  return Eigen::Map<const Eigen::VectorXd>(checked.data(), checked.shape(0));
}

// Finite configurations, one per row: (rows, dof). rows_name names the row count in the error
// ("(G, 7)"); fixed_rows >= 0 requires that many rows.
inline Rows configuration_rows(const Robot& robot, const Array& a, const char* what, const char* rows_name = "N",
                               py::ssize_t fixed_rows = -1) {
  const std::string n = fixed_rows >= 0 ? std::to_string(fixed_rows) : std::string(rows_name);
  const std::string desc = "(" + n + ", " + std::to_string(robot.dof()) + ")";
  require_shape(what, a, {fixed_rows, robot.dof()}, desc.c_str());
  require_finite_array(what, a);
  return Eigen::Map<const Rows>(a.data(), a.shape(0), a.shape(1));
}

// Finite configuration blocks (G, m, dof) as G matrices (m, dof); G given (>= 0) or any (-1).
inline std::vector<Rows> configuration_blocks(const Robot& robot, const Array& a, const char* what, py::ssize_t count) {
  const int dof = robot.dof();
  const std::string desc = "(G, m, " + std::to_string(dof) + ")";
  require_shape(what, a, {count, -1, dof}, desc.c_str());
  require_finite_array(what, a);
  std::vector<Rows> out;
  const py::ssize_t m = a.shape(1);
  for (py::ssize_t g = 0; g < a.shape(0); ++g) out.push_back(Eigen::Map<const Rows>(a.data() + g * m * dof, m, dof));
  return out;
}

// A 1-D array of any length.
inline Eigen::VectorXd vector_arg(const Array& a, const char* what) {
  if (a.ndim() != 1)
    throw std::invalid_argument(std::string(what) + ": expected a 1-D array, got shape " + shape_str(a));
  return Eigen::Map<const Eigen::VectorXd>(a.data(), a.shape(0));
}

// Finite points (N, 3).
inline Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> points_arg(const Array& a, const char* what) {
  require_shape(what, a, {-1, 3}, "(N, 3)");
  require_finite_array(what, a);
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(a.data(), a.shape(0), 3);
}

// A triangle mesh: vertices (V, 3) and faces (F, 3) of vertex indices ("<what> vertices: ...").
inline TriangleMesh mesh_arg(const Array& V, const py::object& face_values, const std::string& what) {
  require_shape((what + " vertices").c_str(), V, {-1, 3}, "(V, 3)");
  const IntArray F = index_array((what + " faces").c_str(), face_values, kMaxIndex);
  require_shape((what + " faces").c_str(), F, {-1, 3}, "(F, 3)");
  TriangleMesh m;
  m.vertices = Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor>>(V.data(), V.shape(0), 3);
  m.faces = Eigen::Map<const Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor>>(F.data(), F.shape(0), 3);
  return m;
}

// A matrix as a new (rows, cols) array.
inline py::array_t<double> rows_array(const Rows& t) {
  py::array_t<double> out({t.rows(), t.cols()});
  Eigen::Map<Rows>(out.mutable_data(), t.rows(), t.cols()) = t;
  return out;
}

// Equal-shape matrices (rows, cols each) as one new (count, rows, cols) array.
inline py::array_t<double> stacked_array(const std::vector<Rows>& blocks, py::ssize_t rows, py::ssize_t cols) {
  const py::ssize_t n = static_cast<py::ssize_t>(blocks.size());
  py::array_t<double> out({n, rows, cols});
  for (py::ssize_t g = 0; g < n; ++g) Eigen::Map<Rows>(out.mutable_data() + g * rows * cols, rows, cols) = blocks[g];
  return out;
}

// Flags (0 or not) as a new boolean mask.
template <typename Flag>
py::array_t<bool> mask_array(const std::vector<Flag>& flags) {
  py::array_t<bool> out(static_cast<py::ssize_t>(flags.size()));
  for (std::size_t k = 0; k < flags.size(); ++k) out.mutable_data()[k] = flags[k] != 0;
  return out;
}

}  // namespace pickplan::bind
