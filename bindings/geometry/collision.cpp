// Bindings of the FCL collision checker (pickplan/collision.hpp).
#include "pickplan/geometry/collision.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace pickplan::bind {

namespace {

std::unique_ptr<CollisionChecker> make_checker(const Robot& robot, const py::list& link_meshes, const py::list& objects,
                                               const py::object& table_size, const py::object& table_pose,
                                               const CollisionSettings& settings) {
  std::vector<LinkMesh> links;
  for (const auto& item : link_meshes) {
    auto t = item.cast<py::tuple>();
    if (t.size() == 2 && py::isinstance<CollisionShape>(t[1])) {  // a prebuilt shape: shared, not rebuilt
      links.push_back({t[0].cast<std::string>(), TriangleMesh{}, t[1].cast<std::shared_ptr<CollisionShape>>()});
      continue;
    }
    if (t.size() != 3)
      throw std::invalid_argument("link_meshes: expected (link name, vertices, faces) or (link name, shape) tuples");
    auto name = t[0].cast<std::string>();
    links.push_back({name, mesh_arg(t[1].cast<Array>(), t[2], "mesh of link '" + name + "'")});
  }
  std::vector<SceneObject> objs;
  for (const auto& item : objects) {
    auto t = item.cast<py::tuple>();
    const bool prebuilt = t.size() == 3 && py::isinstance<CollisionShape>(t[1]);
    if (t.size() != 4 && !prebuilt)
      throw std::invalid_argument(
          "objects: expected (name, vertices, faces, pose 4x4) or (name, shape, pose 4x4) tuples");
    auto name = t[0].cast<std::string>();
    const std::string what = "object '" + name + "'";
    const Transform pose =
        Transform::from_matrix(matrix4(t[prebuilt ? 2 : 3].cast<Array>(), ("pose of " + what).c_str()));
    if (prebuilt)
      objs.push_back({name, TriangleMesh{}, pose, t[1].cast<std::shared_ptr<CollisionShape>>()});
    else
      objs.push_back({name, mesh_arg(t[1].cast<Array>(), t[2], what), pose});
  }
  TableBox table;
  if (!table_size.is_none()) {
    Array s = table_size.cast<Array>();
    require_shape("table size", s, {3}, "(3,)");
    require_finite_array("table size", s);
    table.size = Eigen::Vector3d(s.at(0), s.at(1), s.at(2));
    if (table.size.isZero()) throw std::invalid_argument("table size: expected 3 positive extents, got zeros");
    table.pose =
        table_pose.is_none() ? Transform{} : Transform::from_matrix(matrix4(table_pose.cast<Array>(), "table pose"));
  }
  py::gil_scoped_release release;
  return std::make_unique<CollisionChecker>(robot, std::move(links), std::move(objs), table, settings);
}

}  // namespace

void init_collision(py::module_& m) {
  py::class_<CollisionSettings>(m, "CollisionSettings", "Options of the FCL collision checker (see collision.hpp).")
      .def(py::init<>())
      .def_readwrite("allowed_pairs", &CollisionSettings::allowed_pairs)
      .def_readwrite("excluded_objects", &CollisionSettings::excluded_objects)
      .def_readwrite("self_collision", &CollisionSettings::self_collision)
      .def_readwrite("self_collision_reference", &CollisionSettings::self_collision_reference)
      .def_readwrite("margin", &CollisionSettings::margin)
      .def_readwrite("detect_containment", &CollisionSettings::detect_containment);

  py::enum_<OtherKind>(m, "OtherKind", "What a robot link is near: an object, the table or another link.")
      .value("object", OtherKind::Object)
      .value("table", OtherKind::Table)
      .value("link", OtherKind::Link);
  result_class<ContactInfo>(m, "ContactInfo", "A link near (or in) something: signed distance and world points.")
      .field("link", &ContactInfo::link)
      .field("other", &ContactInfo::other)
      .field("kind", &ContactInfo::kind)
      .field("distance", &ContactInfo::distance)
      .field("point_link", &ContactInfo::point_link)
      .field("point_other", &ContactInfo::point_other);

  py::class_<CollisionShape, std::shared_ptr<CollisionShape>>(
      m, "CollisionShape", "A mesh with its FCL BVH, built once and shared by every checker that places it.")
      .def(py::init([](const Array& V, const py::object& F, const std::string& what) {
             TriangleMesh mesh = mesh_arg(V, F, what);
             py::gil_scoped_release release;
             return std::make_shared<CollisionShape>(std::move(mesh), what);
           }),
           py::arg("vertices"), py::arg("faces"), py::arg("what") = "mesh")
      .def_property_readonly("num_vertices", [](const CollisionShape& s) { return s.mesh().num_vertices(); })
      .def_property_readonly("num_faces", [](const CollisionShape& s) { return s.mesh().num_faces(); });

  py::class_<CollisionChecker>(
      m, "CollisionChecker", "Immutable FCL collision checker: robot link meshes against scene meshes and a table box.")
      .def(py::init(&make_checker), py::arg("robot"), py::arg("link_meshes"), py::arg("objects"),
           py::arg("table_size") = py::none(), py::arg("table_pose") = py::none(),
           py::arg("settings") = CollisionSettings{},
           "link_meshes: [(link, V (n,3), F (m,3))] in link frames; objects: [(name, V, F, pose 4x4)]; a "
           "CollisionShape may stand for V, F.")
      .def_property_readonly("num_pairs", &CollisionChecker::num_pairs)
      .def_property_readonly("checked_pairs", &CollisionChecker::checked_pairs)
      .def_property_readonly("object_names", &CollisionChecker::object_names)
      .def(
          "set_object_pose",
          [](CollisionChecker& c, const std::string& name, const Array& pose) {
            c.set_object_pose(name, Transform::from_matrix(matrix4(pose, "object pose")));
          },
          py::arg("name"), py::arg("pose"), "Move the object `name` (a 4x4 rigid pose).")
      .def_property_readonly("settings", &CollisionChecker::settings)
      .def(
          "in_collision",
          [](const CollisionChecker& c, const Array& q) {
            Eigen::VectorXd v = configuration_vector(c.robot(), q);
            py::gil_scoped_release release;
            return c.in_collision(v);
          },
          py::arg("q"))
      .def(
          "min_distance",
          [](const CollisionChecker& c, const Array& q) {
            Eigen::VectorXd v = configuration_vector(c.robot(), q);
            py::gil_scoped_release release;
            return c.min_distance(v);
          },
          py::arg("q"))
      .def(
          "in_collision_batch",
          [](const CollisionChecker& c, const Array& Q_in, int threads) {
            Array Q = configurations(c.robot(), Q_in);
            const long B = static_cast<long>(Q.shape(0));
            py::array_t<bool> out(B);
            bool* o = out.mutable_data();
            const double* q = Q.data();
            {
              py::gil_scoped_release release;
              c.in_collision_batch(q, B, o, threads);
            }
            return out;
          },
          py::arg("Q"), py::arg("threads") = 1)
      .def(
          "min_distance_batch",
          [](const CollisionChecker& c, const Array& Q_in, int threads) {
            Array Q = configurations(c.robot(), Q_in);
            const long B = static_cast<long>(Q.shape(0));
            py::array_t<double> out(B);
            double* o = out.mutable_data();
            const double* q = Q.data();
            {
              py::gil_scoped_release release;
              c.min_distance_batch(q, B, o, threads);
            }
            return out;
          },
          py::arg("Q"), py::arg("threads") = 1)
      .def(
          "contacts",
          [](const CollisionChecker& c, const Array& q, double within) {
            Eigen::VectorXd v = configuration_vector(c.robot(), q);
            std::vector<ContactInfo> found;
            {
              py::gil_scoped_release release;
              found = c.contacts(v, within);
            }
            return found;
          },
          py::arg("q"), py::arg("within") = 0.0);
}

}  // namespace pickplan::bind
