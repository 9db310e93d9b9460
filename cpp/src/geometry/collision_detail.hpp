#pragma once
// Internal to the collision sources (collision.cpp, collision_shape.cpp): the FCL geometry behind a
// CollisionShape, and the bounds both need.
#include <memory>

#include <fcl/fcl.h>
#include <Eigen/Geometry>

#include "pickplan/geometry/collision.hpp"

namespace pickplan::geometry {

struct CollisionShape::Bvh {
  std::shared_ptr<fcl::CollisionGeometryd> model;  // a BVH, or a solid primitive
};

namespace detail {

// The axis-aligned box of a mesh's vertices moved by T.
inline Eigen::AlignedBox3d bounds(const TriangleMesh& m, const core::Transform& T = core::Transform{}) {
  Eigen::AlignedBox3d box;
  for (int i = 0; i < m.num_vertices(); ++i) box.extend(T.apply(m.vertices.row(i).transpose()));
  return box;
}

}  // namespace detail
}  // namespace pickplan::geometry
