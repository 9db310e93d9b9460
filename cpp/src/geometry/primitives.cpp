// Closed-form signed distances of the solid primitives.
#include "pickplan/geometry/primitives.hpp"

#include <cmath>
#include <stdexcept>

#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {

void Primitive::validate(const std::string& what) const {
  const int used = kind == PrimitiveKind::Box ? 3 : kind == PrimitiveKind::Cylinder ? 2 : 1;
  for (int i = 0; i < used; ++i)
    if (!(std::isfinite(size[i]) && size[i] > 0))
      throw std::invalid_argument(what + ": primitive dimensions must be finite and > 0, got " +
                                  std::to_string(size[i]));
}

namespace {

// Capped cylinder about z: radius r, half length h. In the (radial, axial) half-plane it is a
// rectangle, so the distance is a 2-D box distance; the gradient maps back through the radial
// direction (any direction on the axis itself, where it is not defined).
double cylinder_distance(const Eigen::Vector3d& p, double r, double h, Eigen::Vector3d* gradient) {
  const double rho = std::hypot(p.x(), p.y());
  const double dr = rho - r, dz = std::abs(p.z()) - h;
  const Eigen::Vector2d radial = rho > 0 ? Eigen::Vector2d(p.x() / rho, p.y() / rho) : Eigen::Vector2d(1.0, 0.0);
  const double sz = p.z() < 0 ? -1.0 : 1.0;
  double d, gr, gz;
  if (dr > 0 && dz > 0) {
    d = std::hypot(dr, dz);
    gr = dr / d, gz = dz / d;
  } else if (dr > dz) {
    d = dr, gr = 1.0, gz = 0.0;
  } else {
    d = dz, gr = 0.0, gz = 1.0;
  }
  if (gradient) *gradient = Eigen::Vector3d(gr * radial.x(), gr * radial.y(), gz * sz);
  return d;
}

}  // namespace

double Primitive::signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient) const {
  switch (kind) {
    case PrimitiveKind::Box:
      return box_signed_distance(p, 0.5 * size, gradient);
    case PrimitiveKind::Cylinder:
      return cylinder_distance(p, size.x(), 0.5 * size.y(), gradient);
    case PrimitiveKind::Sphere: {
      const double n = p.norm();
      if (gradient) *gradient = n > 0 ? Eigen::Vector3d(p / n) : Eigen::Vector3d::UnitZ();
      return n - size.x();
    }
  }
  return 0.0;
}

std::pair<double, int> Primitive::deepest(const std::vector<Eigen::Vector3d>& points,
                                          const core::Transform& world_to_frame) const {
  std::pair<double, int> out{0.0, -1};
  for (size_t i = 0; i < points.size(); ++i) {
    const double depth = -signed_distance(world_to_frame.apply(points[i]));
    if (depth > out.first) out = {depth, static_cast<int>(i)};
  }
  return out;
}

Eigen::AlignedBox3d Primitive::bounds() const {
  Eigen::Vector3d h;
  switch (kind) {
    case PrimitiveKind::Box:
      h = 0.5 * size;
      break;
    case PrimitiveKind::Cylinder:
      h = Eigen::Vector3d(size.x(), size.x(), 0.5 * size.y());
      break;
    default:
      h = Eigen::Vector3d::Constant(size.x());
  }
  return Eigen::AlignedBox3d(-h, h);
}

TriangleMesh Primitive::enclosing_mesh() const {
  switch (kind) {
    case PrimitiveKind::Box:
      return TriangleMesh::box(size);
    case PrimitiveKind::Cylinder: {
      // The polygon's edges touch the circle when its vertices stand at r / cos(pi / sections).
      const int sections = 32;
      return TriangleMesh::cylinder(size.x() / std::cos(M_PI / sections), size.y(), sections);
    }
    default: {
      // A UV sphere's facets lie inside the sphere through its vertices: scale it out by the
      // worst facet's inward offset (ring and sector steps each at most pi / 12 from the sphere).
      const int rings = 12, sectors = 24;
      const double scale = 1.0 / (std::cos(M_PI / (2 * rings)) * std::cos(M_PI / sectors));
      return TriangleMesh::sphere(size.x() * scale, rings, sectors);
    }
  }
}

}  // namespace pickplan::geometry
