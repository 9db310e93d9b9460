#include "pickplan/omg/isf.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"
#include "refiner_holder.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

void init_isf(py::module_& m) {
  py::class_<IsfSettings>(m, "IsfSettings")
      .def(py::init<>())
      .def_readwrite("alpha", &IsfSettings::alpha)
      .def_readwrite("beta", &IsfSettings::beta)
      .def_readwrite("gamma", &IsfSettings::gamma)
      .def_readwrite("step_size", &IsfSettings::step_size)
      .def_readwrite("max_halvings", &IsfSettings::max_halvings)
      .def_readwrite("length_unit", &IsfSettings::length_unit)
      .def_readwrite("hand_epsilon", &IsfSettings::hand_epsilon)
      .def_readwrite("arm_epsilon", &IsfSettings::arm_epsilon)
      .def_readwrite("max_joint_step", &IsfSettings::max_joint_step)
      .def_readwrite("active", &IsfSettings::active);
  result_class<GraspTerms>(m, "GraspTerms", "f_grasp's terms (eq. 10) and the contacts matched.")
      .field("pml", &GraspTerms::pml)
      .field("align", &GraspTerms::align)
      .field("isf", &GraspTerms::isf)
      .field("hand", &GraspTerms::hand)
      .field("obstacle", &GraspTerms::obstacle)
      .field("collision", &GraspTerms::collision)
      .field("total", &GraspTerms::total)
      .field("matched", &GraspTerms::matched);

  using Holder = RefinerHolder;
  py::class_<Holder>(m, "GraspRefiner", "C-Space ISF (Algorithm 1) for one target object in one scene.")
      .def(py::init([](std::shared_ptr<Robot> robot, const py::object& hand_link, const Array& contacts,
                       const Array& normals, std::shared_ptr<SceneSdf> hand_sdf, const Array& object_points,
                       const Array& object_normals, std::shared_ptr<SceneSdf> scene, const py::object& body_link_values,
                       const Array& body_points, std::uint64_t exclude_mask, const IsfSettings& settings) {
             BodyPoints body;
             body.points = points_arg(body_points, "body points");
             if (!robot) throw std::invalid_argument("robot: expected a Robot, got None");
             const IntArray body_links = index_array("body_links", body_link_values, robot->num_links());
             if (body_links.ndim() != 1 || body_links.shape(0) != body_points.shape(0))
               throw std::invalid_argument("body links: expected one link index per body point");
             body.link.assign(body_links.data(), body_links.data() + body_links.shape(0));
             const int hand = link_arg(*robot, hand_link);
             auto refiner = std::make_shared<GraspRefiner>(
                 robot, hand, points_arg(contacts, "contact points"), points_arg(normals, "contact normals"), hand_sdf,
                 points_arg(object_points, "object points"), points_arg(object_normals, "object normals"), scene,
                 std::move(body), exclude_mask, settings);
             return Holder{robot, refiner};
           }),
           py::arg("robot"), py::arg("hand_link"), py::arg("contacts"), py::arg("normals"), py::arg("hand_sdf"),
           py::arg("object_points"), py::arg("object_normals"), py::arg("scene"), py::arg("body_links"),
           py::arg("body_points"), py::arg("exclude_mask"), py::arg("settings"))
      .def(
          "cost",
          [](const Holder& h, const Array& q) {
            Eigen::VectorXd qq = configuration_vector(*h.robot, q), g;
            GraspTerms t;
            {
              py::gil_scoped_release release;
              t = h.refiner->cost(qq, &g);
            }
            return py::make_tuple(t, g);
          },
          py::arg("q"), "f_grasp terms and the gradient with respect to q.")
      .def(
          "with_object",
          [](const Holder& h, const Array& object_points, const Array& object_normals, const Array& motion) {
            return Holder{h.robot, h.refiner->with_object(points_arg(object_points, "object points"),
                                                          points_arg(object_normals, "object normals"),
                                                          pose_arg(motion, "motion"))};
          },
          py::arg("object_points"), py::arg("object_normals"), py::arg("motion"),
          "This refiner for the target's surface samples (world) at another place: the target moved by the "
          "4x4 rigid `motion` (this refiner's points onto the new ones); its k-d tree is shared.")
      .def(
          "set_support",
          [](Holder& h, const Array& finger_vertices, const Array& normal, double offset) {
            SupportPlane support;
            support.finger_vertices = points_arg(finger_vertices, "finger vertices");
            require_shape("normal", normal, {3}, "(3,)");
            require_finite_array("normal", normal);
            support.normal = Eigen::Map<const Eigen::Vector3d>(normal.data());
            support.offset = offset;
            h.refiner->set_support(std::move(support));
          },
          py::arg("finger_vertices"), py::arg("normal"), py::arg("offset"),
          "The support plane ISF steps may not press the fingers deeper into (vertices in the hand frame).")
      .def(
          "support_depth",
          [](const Holder& h, const Array& q) { return h.refiner->support_depth(configuration_vector(*h.robot, q)); },
          py::arg("q"), "How far the fingers reach below the support plane at q (m; -inf without one).")
      .def(
          "refine",
          [](const Holder& h, const Array& q, int iterations) {
            if (iterations < 0) throw std::invalid_argument("iterations must be >= 0");
            Eigen::VectorXd qq = configuration_vector(*h.robot, q), out;
            GraspTerms t;
            {
              py::gil_scoped_release release;
              out = h.refiner->refine(qq, iterations, &t);
            }
            return py::make_tuple(out, t);
          },
          py::arg("q"), py::arg("iterations") = 1, "Algorithm 1 steps; returns (q, terms at q).");
}

}  // namespace pickplan::bind
