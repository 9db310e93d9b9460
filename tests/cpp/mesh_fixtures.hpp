#pragma once
// Small meshes built in code for the C++ tests.
#include "pickplan/geometry/sdf.hpp"

namespace pickplan::test {

// Axis-aligned box centred at the origin, outward-facing triangles.
inline void box_mesh(const Eigen::Vector3d& size, geometry::Vertices& V, geometry::Faces& F) {
  const Eigen::Vector3d h = size / 2;
  V.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    V.row(i) << ((i & 1) ? h.x() : -h.x()), ((i & 2) ? h.y() : -h.y()), ((i & 4) ? h.z() : -h.z());
  F.resize(12, 3);
  F << 0, 2, 1, 1, 2, 3,  // z-
      4, 5, 6, 5, 7, 6,   // z+
      0, 1, 4, 1, 5, 4,   // y-
      2, 6, 3, 3, 6, 7,   // y+
      0, 4, 2, 2, 4, 6,   // x-
      1, 3, 5, 3, 7, 5;   // x+
}

}  // namespace pickplan::test
