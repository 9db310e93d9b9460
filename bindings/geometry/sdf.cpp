#include "pickplan/geometry/sdf.hpp"
#include "../common.hpp"
#include "../convert.hpp"
#include "../results.hpp"
#include "pickplan/geometry/frame_clearance.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace pickplan::bind {

namespace {

std::uint64_t exclusion_mask(const SceneSdf& scene, const std::vector<int>& exclude, bool exclude_table) {
  std::uint64_t mask = exclude_table ? SceneSdf::kTableBit : 0;
  for (int i : exclude) {
    if (i < 0 || i >= scene.num_objects())
      throw std::invalid_argument("exclude: object index " + std::to_string(i) + " out of range [0, " +
                                  std::to_string(scene.num_objects()) + ")");
    mask |= std::uint64_t{1} << i;
  }
  return mask;
}

// A merged grid's size and settings when asked (bricks fill on first lookup: `filled` grows).
struct MergedSdfInfo {
  long bricks = 0, filled = 0, cells = 0;  // bricks: cells that may hold a brick
  std::size_t bytes = 0;
  double resolution = 0, cutoff = 0;
  std::uint64_t exclude_mask = 0;
};

Array checked_points(const Array& pts) {
  require_shape("points", pts, {-1, 3}, "(N, 3)");
  require_finite_array("points", pts);
  return pts;
}

}  // namespace

void init_sdf(py::module_& m) {
  result_class<SdfBuildReport>(m, "SdfBuildReport",
                               "What building a grid from a mesh found: skipped faces, sign votes.")
      .field("degenerate_faces", &SdfBuildReport::degenerate_faces)
      .field("sign_disagreement", &SdfBuildReport::sign_disagreement);
  result_class<MergedSdfInfo>(m, "MergedSdfInfo", "A merged grid's bricks, cells, bytes and settings.")
      .field("bricks", &MergedSdfInfo::bricks)
      .field("filled", &MergedSdfInfo::filled)
      .field("cells", &MergedSdfInfo::cells)
      .field("bytes", &MergedSdfInfo::bytes)
      .field("resolution", &MergedSdfInfo::resolution)
      .field("cutoff", &MergedSdfInfo::cutoff)
      .field("exclude_mask", &MergedSdfInfo::exclude_mask);

  py::class_<SdfGrid, std::shared_ptr<SdfGrid>>(m, "SdfGrid",
                                                "Dense signed distance grid of one mesh (grid frame = mesh frame).")
      .def_static(
          "build",
          [](const Array& V, const py::object& face_values, double resolution, double margin) {
            require_shape("vertices", V, {-1, 3}, "(N, 3)");
            const IntArray F = index_array("faces", face_values, kMaxIndex);
            if (F.ndim() != 2 || F.shape(1) != 3)
              throw std::invalid_argument("faces: expected shape (M, 3), got " + shape_str(F));
            Vertices Vm = Eigen::Map<const Vertices>(V.data(), V.shape(0), 3);
            Faces Fm = Eigen::Map<const Faces>(F.data(), F.shape(0), 3);
            SdfBuildReport report;
            std::shared_ptr<SdfGrid> grid;
            {
              py::gil_scoped_release release;
              grid = std::make_shared<SdfGrid>(SdfGrid::build(Vm, Fm, {resolution, margin}, &report));
            }
            return py::make_tuple(grid, report);
          },
          py::arg("vertices"), py::arg("faces"), py::arg("resolution") = 0.005, py::arg("margin") = 0.2,
          "Build from a triangle mesh; returns (grid, report).")
      .def_static(
          "from_values",
          [](const Eigen::Vector3d& origin, double resolution,
             const py::array_t<float, py::array::c_style | py::array::forcecast>& values) {
            if (values.ndim() != 3)
              throw std::invalid_argument("values: expected a 3-D array (nz, ny, nx), got " + shape_str(values));
            std::vector<float> v(values.data(), values.data() + values.size());
            Eigen::Vector3i dims(values.shape(2), values.shape(1), values.shape(0));
            return std::make_shared<SdfGrid>(SdfGrid::from_values(origin, resolution, dims, std::move(v)));
          },
          py::arg("origin"), py::arg("resolution"), py::arg("values"))
      .def_property_readonly("origin", &SdfGrid::origin)
      .def_property_readonly("resolution", &SdfGrid::resolution)
      .def_property_readonly("upper", &SdfGrid::upper)
      .def_property_readonly("shape",
                             [](const SdfGrid& g) { return py::make_tuple(g.dims().z(), g.dims().y(), g.dims().x()); })
      .def_property_readonly(
          "values",
          [](const SdfGrid& g) {
            py::array_t<float> out({g.dims().z(), g.dims().y(), g.dims().x()});
            std::copy(g.values().begin(), g.values().end(), out.mutable_data());
            return out;
          },
          "Node values, array (nz, ny, nx) float32 (x fastest).")
      .def(
          "distance",
          [](const SdfGrid& g, const Array& pts_in) {
            Array pts = checked_points(pts_in);
            const py::ssize_t n = pts.shape(0);
            py::array_t<double> d(n), grad({n, py::ssize_t{3}});
            double* dp = d.mutable_data();
            double* gp = grad.mutable_data();
            const double* p = pts.data();
            {
              py::gil_scoped_release release;
              Eigen::Vector3d gr;
              for (py::ssize_t i = 0; i < n; ++i) {
                dp[i] = g.distance(Eigen::Map<const Eigen::Vector3d>(p + 3 * i), &gr);
                Eigen::Map<Eigen::Vector3d>(gp + 3 * i) = gr;
              }
            }
            return py::make_tuple(d, grad);
          },
          py::arg("points"), "Trilinear signed distance and gradient at (N, 3) grid-frame points.");

  py::class_<SceneSdf, std::shared_ptr<SceneSdf>>(m, "SceneSdf", "Posed SDF grids plus a table box.")
      .def(py::init<>())
      .def(
          "add_object",
          [](SceneSdf& s, std::shared_ptr<SdfGrid> grid, const Array& pose) {
            return s.add_object(std::move(grid), Transform::from_matrix(matrix4(pose, "object pose")));
          },
          py::arg("grid"), py::arg("pose"))
      .def(
          "set_table",
          [](SceneSdf& s, const Eigen::Vector3d& size, const Array& pose) {
            s.set_table(size, Transform::from_matrix(matrix4(pose, "table pose")));
          },
          py::arg("size"), py::arg("pose"))
      .def(
          "set_pose",
          [](SceneSdf& s, int index, const Array& pose) {
            s.set_pose(index, Transform::from_matrix(matrix4(pose, "object pose")));
          },
          py::arg("index"), py::arg("pose"),
          "Move object `index`: it is left out of the merged grids from then on and queried on its own grid.")
      .def(
          "merge",
          [](SceneSdf& s, const std::vector<int>& exclude, double resolution, double cutoff, int brick) {
            const std::uint64_t mask = exclusion_mask(s, exclude, false);
            py::gil_scoped_release release;
            s.merge(mask, MergedSdfSettings{resolution, cutoff, brick});
          },
          py::arg("exclude") = std::vector<int>{}, py::arg("resolution") = MergedSdfSettings{}.resolution,
          py::arg("cutoff") = MergedSdfSettings{}.cutoff, py::arg("brick") = MergedSdfSettings{}.brick,
          "Resample the objects not in `exclude` into one world-frame bricked grid, clamped at cutoff: queries "
          "with that exclusion and a cutoff <= this one then take one lookup.")
      .def_property_readonly("merged_masks", &SceneSdf::merged_masks,
                             "Object exclusion masks with a merged grid, in the order they were merged.")
      .def_property_readonly("merged_info",
                             [](const SceneSdf& s) -> std::optional<MergedSdfInfo> {
                               const MergedSdf* m = s.merged();
                               if (!m) return std::nullopt;
                               return MergedSdfInfo{m->num_bricks(),  m->num_filled(),          m->num_cells(),
                                                    m->bytes(),       m->settings().resolution, m->cutoff(),
                                                    m->exclude_mask()};
                             })
      .def(
          "lower_bound",
          [](const SceneSdf& s, const Array& pts_in, const std::vector<int>& exclude, bool exclude_table) {
            Array pts = checked_points(pts_in);
            const std::uint64_t mask = exclusion_mask(s, exclude, exclude_table);
            py::array_t<double> out(pts.shape(0));
            double* o = out.mutable_data();
            const double* p = pts.data();
            py::gil_scoped_release release;
            for (py::ssize_t i = 0; i < pts.shape(0); ++i)
              o[i] = s.lower_bound(Eigen::Map<const Eigen::Vector3d>(p + 3 * i), mask);
            return out;
          },
          py::arg("points"), py::arg("exclude") = std::vector<int>{}, py::arg("exclude_table") = false,
          "Cheap lower bounds of the distance (used to cull links far from every obstacle).")
      .def_property_readonly("num_objects", &SceneSdf::num_objects)
      .def_property_readonly("has_table", &SceneSdf::has_table)
      .def(
          "distance",
          [](const SceneSdf& s, const Array& pts_in, double cutoff, const std::vector<int>& exclude, bool exclude_table,
             bool reference) {
            Array pts = checked_points(pts_in);
            const std::uint64_t mask = exclusion_mask(s, exclude, exclude_table);
            const py::ssize_t n = pts.shape(0);
            py::array_t<double> d(n), grad({n, py::ssize_t{3}});
            double* dp = d.mutable_data();
            double* gp = grad.mutable_data();
            const double* p = pts.data();
            {
              py::gil_scoped_release release;
              if (!reference) {
                s.distances(p, n, dp, gp, cutoff, mask);
              } else {
                for (py::ssize_t i = 0; i < n; ++i) {
                  Eigen::Vector3d g;
                  dp[i] = s.distance_unmerged(Eigen::Map<const Eigen::Vector3d>(p + 3 * i), &g, cutoff, mask);
                  Eigen::Map<Eigen::Vector3d>(gp + 3 * i) = g;
                }
              }
            }
            return py::make_tuple(d, grad);
          },
          py::arg("points"), py::arg("cutoff") = std::numeric_limits<double>::infinity(),
          py::arg("exclude") = std::vector<int>{}, py::arg("exclude_table") = false, py::arg("reference") = false,
          "Signed distance to the nearest body and its gradient for (N, 3) world points. Bodies farther than "
          "cutoff are skipped (the result is then cutoff with a zero gradient). reference: by the per-object "
          "grids only, as the success test measures (not a merged grid's resampling).")
      .def(
          "clear_in_frames",
          [](const SceneSdf& s, const Array& frames, const Array& pts_in, bool inverse, double reach, double threshold,
             double cutoff, const std::vector<int>& exclude, bool exclude_table) {
            require_shape("frames", frames, {-1, 4, 4}, "(K, 4, 4)");
            Array pts = checked_points(pts_in);
            FrameClearance settings;
            settings.inverse = inverse;
            settings.reach = reach;
            settings.threshold = threshold;
            settings.cutoff = cutoff;
            settings.exclude_mask = exclusion_mask(s, exclude, exclude_table);
            const FrameMatrix F = Eigen::Map<const FrameMatrix>(frames.data(), frames.shape(0), 16);
            const FrameMatrix P = Eigen::Map<const FrameMatrix>(pts.data(), pts.shape(0), 3);
            std::vector<std::uint8_t> clear;
            {
              py::gil_scoped_release release;
              clear = clear_in_frames(F, P, s, settings);
            }
            return mask_array(clear);
          },
          py::arg("frames"), py::arg("points"), py::arg("inverse"), py::arg("reach"), py::arg("threshold"),
          py::arg("cutoff"), py::arg("exclude") = std::vector<int>{}, py::arg("exclude_table") = false,
          "Per frame: every point read (inverse: world points taken into the frame, those within reach of its "
          "origin; else frame points taken to the world) farther than threshold from the bodies.");
}

}  // namespace pickplan::bind
