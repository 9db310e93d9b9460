// Bindings of the local sections of grasps from points (pickplan/omg/point_sections.hpp).
#include "pickplan/omg/point_sections.hpp"
#include "../common.hpp"
#include "pickplan/omg/point_queries.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;
using namespace pickplan::omg;

namespace pickplan::bind {

namespace {

using LongArray = py::array_t<long, py::array::c_style | py::array::forcecast>;
using BoolArray = py::array_t<bool, py::array::c_style | py::array::forcecast>;

// The arguments of a radius query: points, query indices, and optionally keep flags and an order.
struct PairQuery {
  RowMatrixXd P;
  std::vector<long> Q, O;
  std::vector<std::uint8_t> K;
  PairQuery(const Array& points, const LongArray& queries, const std::optional<BoolArray>& keep,
            const std::optional<LongArray>& order) {
    require_shape("points", points, {-1, 3}, "(N, 3)");
    require_shape("queries", queries, {-1}, "(M,)");
    P = Eigen::Map<const RowMatrixXd>(points.data(), points.shape(0), 3);
    Q.assign(queries.data(), queries.data() + queries.shape(0));
    if (keep) {
      require_shape("keep", *keep, {points.shape(0)}, "(N,) like points");
      K.assign(keep->data(), keep->data() + keep->shape(0));
    }
    if (order) {
      require_shape("order", *order, {points.shape(0)}, "(N,) like points");
      O.assign(order->data(), order->data() + order->shape(0));
    }
  }
};

}  // namespace

void init_point_sections(py::module_& m) {
  py::class_<SectionSettings>(m, "SectionSettings")
      .def(py::init<>())
      .def_readwrite("pad_width", &SectionSettings::pad_width)
      .def_readwrite("max_width", &SectionSettings::max_width)
      .def_readwrite("gap", &SectionSettings::gap)
      .def_readwrite("trim", &SectionSettings::trim)
      .def_readwrite("min_width", &SectionSettings::min_width)
      .def_readwrite("fit_width", &SectionSettings::fit_width)
      .def_readwrite("face_tolerance", &SectionSettings::face_tolerance);

  m.def(
      "local_sections",
      [](const Array& ry, const Array& rx, const Array& height, const SectionSettings& settings) {
        require_shape("ry", ry, {-1, -1}, "(N, A)");
        require_shape("rx", rx, {ry.shape(0), ry.shape(1)}, "like ry");
        require_shape("height", height, {ry.shape(0)}, "(N,)");
        const RowMatrixXd Y = Eigen::Map<const RowMatrixXd>(ry.data(), ry.shape(0), ry.shape(1));
        const RowMatrixXd X = Eigen::Map<const RowMatrixXd>(rx.data(), rx.shape(0), rx.shape(1));
        const Eigen::VectorXd h = Eigen::Map<const Eigen::VectorXd>(height.data(), height.shape(0));
        std::vector<LocalSection> found;
        {
          py::gil_scoped_release release;
          found = local_sections(Y, X, h, settings);
        }
        // one row per section: yaw, lo, hi, across_min, across_max, top
        py::array_t<double> out({static_cast<py::ssize_t>(found.size()), py::ssize_t(6)});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t k = 0; k < found.size(); ++k) {
          const LocalSection& f = found[k];
          const double row[6] = {double(f.yaw), f.lo, f.hi, f.across_min, f.across_max, f.top};
          for (int c = 0; c < 6; ++c) o(k, c) = row[c];
        }
        return out;
      },
      py::arg("ry"), py::arg("rx"), py::arg("height"), py::arg("settings"),
      "The local sections of grasps from points that pass: rows (yaw, lo, hi, across_min, across_max, top).");

  m.def(
      "points_in_frames",
      [](const Array& frames, const Array& points, const Array& half) {
        require_shape("frames", frames, {-1, 4, 4}, "(K, 4, 4)");
        require_shape("points", points, {-1, 3}, "(N, 3)");
        require_shape("half", half, {frames.shape(0), 3}, "(K, 3)");
        const RowMatrixXd F = Eigen::Map<const RowMatrixXd>(frames.data(), frames.shape(0), 16);
        const RowMatrixXd P = Eigen::Map<const RowMatrixXd>(points.data(), points.shape(0), 3);
        const RowMatrixXd H = Eigen::Map<const RowMatrixXd>(half.data(), half.shape(0), 3);
        py::gil_scoped_release release;
        return Eigen::VectorXi(points_in_frames(F, P, H));
      },
      py::arg("frames"), py::arg("points"), py::arg("half"),
      "Per frame: how many points lie in the box |R^T (p - origin)| < half about its origin.");

  m.def(
      "radius_pairs",
      [](const Array& points, const LongArray& queries, double radius, std::optional<BoolArray> keep,
         std::optional<LongArray> order) {
        const PairQuery q(points, queries, keep, order);
        RadiusPairs found;
        {
          py::gil_scoped_release release;
          found = radius_pairs(q.P, q.Q, radius, q.K, q.O);
        }
        return py::make_tuple(py::array_t<long>(found.i.size(), found.i.data()),
                              py::array_t<long>(found.j.size(), found.j.data()));
      },
      py::arg("points"), py::arg("queries"), py::arg("radius"), py::arg("keep") = py::none(),
      py::arg("order") = py::none(),
      "The pairs (i, j) with |P_j - P_i| <= radius: i the queries in turn, each one's j (only kept ones) in the "
      "place they take in order (a permutation of the points; default ascending).");

  m.def(
      "antipodal_partners",
      [](const Array& points, const Array& normals, const LongArray& queries, double radius,
         std::optional<BoolArray> keep, std::optional<LongArray> order, double min_width, double cone) {
        const PairQuery q(points, queries, keep, order);
        require_shape("normals", normals, {points.shape(0), 3}, "(N, 3) like points");
        const RowMatrixXd N = Eigen::Map<const RowMatrixXd>(normals.data(), normals.shape(0), 3);
        AntipodalPartners found;
        {
          py::gil_scoped_release release;
          found = antipodal_partners(q.P, N, q.Q, radius, q.K, q.O, min_width, cone);
        }
        return py::make_tuple(py::array_t<long>(found.i.size(), found.i.data()),
                              py::array_t<long>(found.j.size(), found.j.data()),
                              py::array_t<double>(found.margins.size(), found.margins.data()),
                              py::array_t<double>(found.widths.size(), found.widths.data()));
      },
      py::arg("points"), py::arg("normals"), py::arg("queries"), py::arg("radius"), py::arg("keep"), py::arg("order"),
      py::arg("min_width"), py::arg("cone"),
      "The radius pairs (as radius_pairs) at least min_width apart within each other's friction cone: (i, j, margins, "
      "widths).");

  m.def(
      "sorted_quantiles",
      [](const Array& v, const Array& q) {
        require_shape("values", v, {-1}, "(N,)");
        require_shape("q", q, {-1}, "(K,)");
        if (v.shape(0) < 1) throw std::invalid_argument("sorted quantiles: no values");
        py::array_t<double> out(q.shape(0));
        for (py::ssize_t k = 0; k < q.shape(0); ++k) out.mutable_at(k) = sorted_quantile(v.data(), v.shape(0), q.at(k));
        return out;
      },
      py::arg("values"), py::arg("q"), "numpy's default quantiles of sorted values (the native sections' helper).");
}

}  // namespace pickplan::bind
