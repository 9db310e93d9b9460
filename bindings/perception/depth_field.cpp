// Bindings of the depth-image world model (pickplan/perception/depth_field.hpp).
#include "pickplan/perception/depth_field.hpp"
#include "../common.hpp"
#include "../results.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::perception;

namespace pickplan::bind {

namespace {

using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
using ByteArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

DepthView view_arg(const FloatArray& depth, const Array& K, const Array& pose, const py::object& target,
                   std::size_t k) {
  const std::string w = "view " + std::to_string(k);
  require_shape((w + " depth").c_str(), depth, {-1, -1}, "(H, W)");
  require_shape((w + " K").c_str(), K, {3, 3}, "(3, 3)");
  DepthView v;
  v.depth = Eigen::Map<const DepthImage>(depth.data(), depth.shape(0), depth.shape(1));
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) v.K(r, c) = K.at(r, c);
  v.camera_pose = Transform::from_matrix(matrix4(pose, (w + " camera pose").c_str()));
  if (!target.is_none()) {
    const ByteArray mask = target.cast<ByteArray>();
    require_shape((w + " target mask").c_str(), mask, {depth.shape(0), depth.shape(1)},
                  ("(" + std::to_string(depth.shape(0)) + ", " + std::to_string(depth.shape(1)) + ")").c_str());
    v.target = Eigen::Map<const PixelMask>(mask.data(), mask.shape(0), mask.shape(1));
  }
  return v;
}

}  // namespace

void init_perception(py::module_& m) {
  py::class_<DepthFieldSettings>(m, "DepthFieldSettings")
      .def(py::init<>())
      .def_readwrite("lo", &DepthFieldSettings::lo)
      .def_readwrite("hi", &DepthFieldSettings::hi)
      .def_readwrite("resolution", &DepthFieldSettings::resolution)
      .def_readwrite("surface_margin", &DepthFieldSettings::surface_margin)
      .def_readwrite("has_plane", &DepthFieldSettings::has_plane)
      .def_readwrite("plane_normal", &DepthFieldSettings::plane_normal)
      .def_readwrite("plane_offset", &DepthFieldSettings::plane_offset)
      .def_readwrite("plane_margin", &DepthFieldSettings::plane_margin)
      .def_readwrite("target_stride", &DepthFieldSettings::target_stride);
  result_class<DepthField>(m, "DepthField",
                           "Fused depth views: the obstacles' grid, the target's points, voxel counts.")
      .computed("obstacles", [](const DepthField& f) { return std::const_pointer_cast<SdfGrid>(f.obstacles); })
      .field("target_points", &DepthField::target_points)
      .field("target_normals", &DepthField::target_normals)
      .field("occupied", &DepthField::occupied)
      .field("target", &DepthField::target)
      .field("free", &DepthField::free);

  m.def(
      "build_depth_field",
      [](const std::vector<FloatArray>& depths, const std::vector<Array>& Ks, const std::vector<Array>& poses,
         const std::vector<py::object>& targets, const DepthFieldSettings& settings) {
        if (Ks.size() != depths.size() || poses.size() != depths.size() || targets.size() != depths.size())
          throw std::invalid_argument(
              "depth field: expected as many intrinsics, poses and target masks as depth "
              "images (" +
              std::to_string(depths.size()) + "), got " + std::to_string(Ks.size()) + ", " +
              std::to_string(poses.size()) + ", " + std::to_string(targets.size()));
        std::vector<DepthView> views;
        for (std::size_t k = 0; k < depths.size(); ++k)
          views.push_back(view_arg(depths[k], Ks[k], poses[k], targets[k], k));
        DepthField f;
        {
          py::gil_scoped_release release;
          f = build_depth_field(views, settings);
        }
        return f;
      },
      py::arg("depths"), py::arg("K"), py::arg("camera_poses"), py::arg("target_masks"), py::arg("settings"),
      "Fuse depth views into a signed distance grid of the obstacles and the target's observed points.");

  m.def(
      "most_inliers",
      [](const Array& points, const Array& normals, const Array& offsets, double tolerance) {
        require_shape("points", points, {-1, 3}, "(N, 3)");
        require_shape("normals", normals, {-1, 3}, "(K, 3)");
        require_shape("offsets", offsets, {normals.shape(0)}, "(K,)");
        const Vertices P = Eigen::Map<const Vertices>(points.data(), points.shape(0), 3);
        const Vertices N = Eigen::Map<const Vertices>(normals.data(), normals.shape(0), 3);
        const Eigen::VectorXd d = Eigen::Map<const Eigen::VectorXd>(offsets.data(), offsets.shape(0));
        PlaneChoice best;
        {
          py::gil_scoped_release release;
          best = most_inliers(P, N, d, tolerance);
        }
        return py::make_tuple(best.index, best.inliers);
      },
      py::arg("points"), py::arg("normals"), py::arg("offsets"), py::arg("tolerance"),
      "The first plane n_k . x = d_k with the most points within tolerance of it: (k, its count); k -1 without "
      "planes.");

  m.def(
      "point_distance_grid",
      [](const Array& points, const Array& origin, double resolution, const IntArray& dims) {
        require_shape("points", points, {-1, 3}, "(N, 3)");
        require_shape("origin", origin, {3}, "(3,)");
        require_shape("dims", dims, {3}, "(3,) nodes along x, y, z");
        const Vertices P = Eigen::Map<const Vertices>(points.data(), points.shape(0), 3);
        const Eigen::Vector3d o(origin.at(0), origin.at(1), origin.at(2));
        const Eigen::Vector3i n(dims.at(0), dims.at(1), dims.at(2));
        std::vector<float> d;
        {
          py::gil_scoped_release release;
          d = point_distance_grid(P, o, resolution, n);
        }
        py::array_t<float> out(
            {static_cast<py::ssize_t>(n.z()), static_cast<py::ssize_t>(n.y()), static_cast<py::ssize_t>(n.x())});
        std::copy(d.begin(), d.end(), out.mutable_data());
        return out;
      },
      py::arg("points"), py::arg("origin"), py::arg("resolution"), py::arg("dims"),
      "(nz, ny, nx) distances from the grid's nodes (origin + resolution * (x, y, z)) to the nearest point.");

  m.def(
      "squared_distance_transform",
      [](const ByteArray& mask) {
        if (mask.ndim() != 3)
          throw std::invalid_argument("mask: expected a 3-D array (nz, ny, nx), got " + shape_str(mask));
        std::vector<std::uint8_t> v(mask.data(), mask.data() + mask.size());
        const Eigen::Vector3i dims(mask.shape(2), mask.shape(1), mask.shape(0));
        std::vector<float> d;
        {
          py::gil_scoped_release release;
          d = squared_distance_transform(v, dims);
        }
        py::array_t<float> out({mask.shape(0), mask.shape(1), mask.shape(2)});
        std::copy(d.begin(), d.end(), out.mutable_data());
        return out;
      },
      py::arg("mask"), "Exact squared Euclidean distance (voxels) to the nearest nonzero voxel.");
}

}  // namespace pickplan::bind
