#pragma once
// Solid primitives (box, cylinder, sphere) as obstacles: exact signed distances in closed form
// (the SDF of a primitive is analytic, no grid), their bounds, and a closed triangle mesh that
// encloses them (for containment probes and display). Frames: centred at the origin, a
// cylinder's axis along z (MoveIt's and URDF's convention).
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "pickplan/geometry/mesh.hpp"

namespace pickplan::geometry {

enum class PrimitiveKind { Box, Cylinder, Sphere };

struct Primitive {
  PrimitiveKind kind = PrimitiveKind::Box;
  // Box: full extents (x, y, z). Cylinder: (radius, length, unused). Sphere: (radius, unused, unused).
  Eigen::Vector3d size = Eigen::Vector3d::Zero();

  static Primitive box(const Eigen::Vector3d& extents) { return {PrimitiveKind::Box, extents}; }
  static Primitive cylinder(double radius, double length) { return {PrimitiveKind::Cylinder, {radius, length, 0.0}}; }
  static Primitive sphere(double radius) { return {PrimitiveKind::Sphere, {radius, 0.0, 0.0}}; }

  // Throws std::invalid_argument ("<what>: ...") for non-finite or non-positive dimensions.
  void validate(const std::string& what) const;
  // Exact signed distance (negative inside) of a point in the primitive's frame; the gradient
  // (unit length wherever it is defined) is written when given.
  double signed_distance(const Eigen::Vector3d& p, Eigen::Vector3d* gradient = nullptr) const;
  // The deepest of `points` (world frame; `world_to_frame` maps them into the primitive's) inside
  // it: (depth >= 0, index), index -1 when none is inside.
  std::pair<double, int> deepest(const std::vector<Eigen::Vector3d>& points,
                                 const core::Transform& world_to_frame) const;
  // Axis-aligned bounds in the primitive's frame.
  Eigen::AlignedBox3d bounds() const;
  // A closed, outward-oriented mesh that contains the primitive (circumscribed polygons).
  TriangleMesh enclosing_mesh() const;
};

}  // namespace pickplan::geometry
