// Bindings of the solid primitives (pickplan/geometry/primitives.hpp).
#include "pickplan/geometry/primitives.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "pickplan/geometry/collision.hpp"
#include "pickplan/geometry/sdf.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace pickplan::bind {

void init_primitives(py::module_& m) {
  py::enum_<PrimitiveKind>(m, "PrimitiveKind")
      .value("box", PrimitiveKind::Box)
      .value("cylinder", PrimitiveKind::Cylinder)
      .value("sphere", PrimitiveKind::Sphere);

  py::class_<Primitive>(m, "Primitive", "A solid box (extents), cylinder (radius, length; axis z) or sphere (radius).")
      .def(py::init([](PrimitiveKind kind, const Eigen::Vector3d& size) {
             Primitive p{kind, size};
             p.validate("primitive");
             return p;
           }),
           py::arg("kind"), py::arg("size"))
      .def_readonly("kind", &Primitive::kind)
      .def_readonly("size", &Primitive::size)
      .def(
          "signed_distance",
          [](const Primitive& p, const Array& points) {
            require_shape("points", points, {-1, 3}, "(N, 3)");
            const long n = static_cast<long>(points.shape(0));
            py::array_t<double> d(n), grad({static_cast<py::ssize_t>(n), static_cast<py::ssize_t>(3)});
            double* dd = d.mutable_data();
            double* gg = grad.mutable_data();
            const double* x = points.data();
            for (long i = 0; i < n; ++i) {
              Eigen::Vector3d g;
              dd[i] = p.signed_distance(Eigen::Vector3d(x[3 * i], x[3 * i + 1], x[3 * i + 2]), &g);
              gg[3 * i] = g.x(), gg[3 * i + 1] = g.y(), gg[3 * i + 2] = g.z();
            }
            return py::make_tuple(d, grad);
          },
          py::arg("points"), "Exact signed distance and gradient at (N, 3) points in the primitive's frame.")
      .def("bounds", [](const Primitive& p) {
        const Eigen::AlignedBox3d b = p.bounds();
        return py::make_tuple(Eigen::Vector3d(b.min()), Eigen::Vector3d(b.max()));
      });

  py::class_<SceneSdf, std::shared_ptr<SceneSdf>> scene_sdf =
      py::reinterpret_borrow<py::class_<SceneSdf, std::shared_ptr<SceneSdf>>>(m.attr("SceneSdf"));
  scene_sdf.def(
      "add_primitive",
      [](SceneSdf& s, const Primitive& p, const Array& pose) {
        const Eigen::Matrix4d M = matrix4(pose, "primitive pose");
        require_rigid("primitive pose", M);
        return s.add_primitive(p, Transform::from_matrix(M));
      },
      py::arg("primitive"), py::arg("pose"), "Adds a solid primitive (closed-form distances); returns its index.");

  py::class_<CollisionShape, std::shared_ptr<CollisionShape>> shape =
      py::reinterpret_borrow<py::class_<CollisionShape, std::shared_ptr<CollisionShape>>>(m.attr("CollisionShape"));
  shape
      .def_static(
          "from_primitive",
          [](const Primitive& p, const std::string& what) { return std::make_shared<CollisionShape>(p, what); },
          py::arg("primitive"), py::arg("what") = "primitive")
      .def_static(
          "convex",
          [](const Array& V, const py::object& F, const std::string& what) {
            return CollisionShape::convex(mesh_arg(V, F, "convex"), what);
          },
          py::arg("vertices"), py::arg("faces"), py::arg("what") = "convex",
          "A convex solid from a convex hull's vertices and faces (FCL's Convex).")
      .def_property_readonly("solid", &CollisionShape::solid);
}

}  // namespace pickplan::bind
