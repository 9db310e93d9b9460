#include "../common.hpp"
#include "../results.hpp"

using namespace pickplan::core;

namespace pickplan::bind {

namespace {

const char* joint_type_name(JointType t) {
  switch (t) {
    case JointType::Fixed:
      return "fixed";
    case JointType::Revolute:
      return "revolute";
    case JointType::Continuous:
      return "continuous";
    case JointType::Prismatic:
      return "prismatic";
  }
  return "?";
}

py::array_t<double> fk(const Robot& robot, const Array& q_in) {
  Array q = configuration(robot, q_in);
  const int L = robot.num_links();
  py::array_t<double> out({L, 4, 4});
  double* o = out.mutable_data();
  RobotWorkspace ws(robot);
  robot.forward_kinematics(q.data(), ws);
  for (int i = 0; i < L; ++i) write_matrix4(ws.link_pose[i], o + 16 * i);
  return out;
}

py::array_t<double> fk_batch(const Robot& robot, const Array& Q_in) {
  Array Q = configurations(robot, Q_in);
  const py::ssize_t B = Q.shape(0);
  const int L = robot.num_links(), d = robot.dof();
  py::array_t<double> out({B, static_cast<py::ssize_t>(L), py::ssize_t{4}, py::ssize_t{4}});
  double* o = out.mutable_data();
  const double* q = Q.data();
  {
    py::gil_scoped_release release;
    RobotWorkspace ws(robot);
    for (py::ssize_t b = 0; b < B; ++b) {
      robot.forward_kinematics(q + b * d, ws);
      for (int i = 0; i < L; ++i) write_matrix4(ws.link_pose[i], o + 16 * (b * L + i));
    }
  }
  return out;
}

py::array_t<double> jacobian(const Robot& robot, const Array& q_in, const py::object& link,
                             const py::object& point_in) {
  Array q = configuration(robot, q_in);
  const int li = link_arg(robot, link);
  Array point = point_in.is_none() ? Array(std::vector<py::ssize_t>{3}) : point_in.cast<Array>();
  if (point_in.is_none()) std::fill(point.mutable_data(), point.mutable_data() + 3, 0.0);
  require_shape("point", point, {3}, "(3,)");
  require_finite_array("point", point);
  RobotWorkspace ws(robot);
  robot.forward_kinematics(q.data(), ws);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, robot.dof());
  robot.point_jacobian(ws, li, Eigen::Vector3d(point.at(0), point.at(1), point.at(2)), J);
  py::array_t<double> out({6, robot.dof()});
  Eigen::Map<Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>>(out.mutable_data(), 6, robot.dof()) = J;
  return out;
}

py::array_t<double> link_jacobians(const Robot& robot, const Array& q_in) {
  Array q = configuration(robot, q_in);
  const int L = robot.num_links(), d = robot.dof();
  py::array_t<double> out({L, 6, d});
  RobotWorkspace ws(robot);
  robot.forward_kinematics(q.data(), ws);
  Eigen::Matrix<double, 6, Eigen::Dynamic> J(6, d);
  for (int i = 0; i < L; ++i) {
    robot.point_jacobian(ws, i, Eigen::Vector3d::Zero(), J);
    Eigen::Map<Eigen::Matrix<double, 6, Eigen::Dynamic, Eigen::RowMajor>>(out.mutable_data() + 6 * d * i, 6, d) = J;
  }
  return out;
}

// Points fixed on links (link index + local coordinates) at every configuration of Q.
py::array_t<double> transform_points(const Robot& robot, const Array& Q_in, const py::object& link_values,
                                     const Array& pts) {
  Array Q = configurations(robot, Q_in);
  const IntArray links = index_array("links", link_values, robot.num_links());
  require_shape("points", pts, {-1, 3}, "(N, 3)");
  require_finite_array("points", pts);
  if (links.ndim() != 1 || links.shape(0) != pts.shape(0))
    throw std::invalid_argument("links: expected shape (" + std::to_string(pts.shape(0)) + ",) matching points, got " +
                                shape_str(links));
  const py::ssize_t N = pts.shape(0), T = Q.shape(0);
  py::array_t<double> out({T, N, py::ssize_t{3}});
  double* o = out.mutable_data();
  const double* q = Q.data();
  const double* p = pts.data();
  const int* l = links.data();
  {
    py::gil_scoped_release release;
    RobotWorkspace ws(robot);
    for (py::ssize_t t = 0; t < T; ++t) {
      robot.forward_kinematics(q + t * robot.dof(), ws);
      for (py::ssize_t j = 0; j < N; ++j) {
        Eigen::Map<Eigen::Vector3d>(o + 3 * (t * N + j)) =
            ws.link_pose[l[j]].apply(Eigen::Map<const Eigen::Vector3d>(p + 3 * j));
      }
    }
  }
  return out;
}

}  // namespace

void init_robot(py::module_& m) {
  py::enum_<CollisionGeometry::Kind>(m, "GeometryKind")
      .value("mesh", CollisionGeometry::Kind::Mesh)
      .value("box", CollisionGeometry::Kind::Box)
      .value("cylinder", CollisionGeometry::Kind::Cylinder)
      .value("sphere", CollisionGeometry::Kind::Sphere);
  result_class<CollisionGeometry>(m, "CollisionGeometry",
                                  "A link's URDF collision geometry (origin in the link frame).")
      .field("kind", &CollisionGeometry::kind)
      .field("mesh_path", &CollisionGeometry::mesh_path)
      .field("scale", &CollisionGeometry::scale)
      .field("size", &CollisionGeometry::size)
      .computed("origin", [](const CollisionGeometry& g) { return Eigen::Matrix4d(g.origin.matrix()); });

  py::class_<Robot, std::shared_ptr<Robot>>(m, "Robot", "Immutable kinematic tree loaded from URDF.")
      .def_static("from_urdf_file", &Robot::from_urdf_file, py::arg("path"),
                  py::arg("package_dirs") = std::vector<std::string>{}, py::call_guard<py::gil_scoped_release>())
      .def_static("from_urdf_string", &Robot::from_urdf_string, py::arg("xml"), py::arg("base_dir"),
                  py::arg("package_dirs") = std::vector<std::string>{}, py::arg("source_name") = "<string>",
                  py::call_guard<py::gil_scoped_release>())
      .def(
          "with_base",
          [](const Robot& r, const Array& T) { return r.with_base(Transform::from_matrix(matrix4(T, "base pose"))); },
          py::arg("base_pose"))
      .def(
          "with_attached_link",
          [](const Robot& r, const std::string& name, const std::string& parent, const Array& T) {
            return r.with_attached_link(name, parent, Transform::from_matrix(matrix4(T, "attached link origin")));
          },
          py::arg("name"), py::arg("parent"), py::arg("origin"))
      .def_property_readonly("name", &Robot::name)
      .def_property_readonly("dof", &Robot::dof)
      .def_property_readonly("num_links", &Robot::num_links)
      .def_property_readonly("link_names", &Robot::link_names)
      .def_property_readonly("joint_names", &Robot::joint_names)
      .def_property_readonly("lower_limits", &Robot::lower_limits)
      .def_property_readonly("upper_limits", &Robot::upper_limits)
      .def_property_readonly("velocity_limits", &Robot::velocity_limits)
      .def_property_readonly("base_pose", [](const Robot& r) { return Eigen::Matrix4d(r.base().matrix()); })
      .def_property_readonly("link_parents",
                             [](const Robot& r) {
                               std::vector<int> v;
                               for (const auto& l : r.links()) v.push_back(l.parent);
                               return v;
                             })
      .def_property_readonly("link_q_index",
                             [](const Robot& r) {
                               std::vector<int> v;
                               for (const auto& l : r.links()) v.push_back(l.q_index);
                               return v;
                             })
      .def_property_readonly("link_joint_types",
                             [](const Robot& r) {
                               std::vector<std::string> v;
                               for (const auto& l : r.links()) v.push_back(joint_type_name(l.joint_type));
                               return v;
                             })
      .def_property_readonly("mimic",
                             [](const Robot& r) {
                               py::dict d;  // joint name -> (source joint name, multiplier, offset)
                               for (const auto& l : r.links())
                                 if (l.mimic.source_q >= 0)
                                   d[py::str(l.joint_name)] = py::make_tuple(r.joint_names()[l.mimic.source_q],
                                                                             l.mimic.multiplier, l.mimic.offset);
                               return d;
                             })
      .def("link_index", &Robot::link_index, py::arg("name"))
      .def(
          "collision_geometries",
          [](const Robot& r, const py::object& link) { return r.link(link_arg(r, link)).collisions; }, py::arg("link"))
      .def("fk", &fk, py::arg("q"), "World pose (4x4) of every link: array (num_links, 4, 4).")
      .def("fk_batch", &fk_batch, py::arg("Q"), "Link poses for a batch (B, dof): array (B, num_links, 4, 4).")
      .def("jacobian", &jacobian, py::arg("q"), py::arg("link"), py::arg("point") = py::none(),
           "6 x dof world Jacobian (linear; angular) of a point fixed on a link (link-frame coordinates).")
      .def("link_jacobians", &link_jacobians, py::arg("q"), "Jacobians of every link origin: (num_links, 6, dof).")
      .def("transform_points", &transform_points, py::arg("Q"), py::arg("links"), py::arg("points"),
           "World positions (T, N, 3) of N link-fixed points along T configurations.");
}

}  // namespace pickplan::bind
