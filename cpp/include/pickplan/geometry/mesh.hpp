#pragma once
// Triangle meshes for collision checking: plain vertex/face arrays, primitive meshes
// (box, cylinder, sphere), a minimal Wavefront OBJ reader (v / f lines), and the collision
// geometry of a robot link as one mesh in the link frame.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/core/transform.hpp"

namespace pickplan::geometry {

struct TriangleMesh {
  Eigen::Matrix<double, Eigen::Dynamic, 3, Eigen::RowMajor> vertices;  // (V, 3)
  Eigen::Matrix<int, Eigen::Dynamic, 3, Eigen::RowMajor> faces;        // (F, 3), 0-based vertex indices

  int num_vertices() const { return static_cast<int>(vertices.rows()); }
  int num_faces() const { return static_cast<int>(faces.rows()); }

  // Throws std::invalid_argument ("<what>: ...") for no faces, NaN/inf vertices, face
  // indices out of range, or a mesh whose faces all have zero area.
  void validate(const std::string& what) const;

  // Copy with every vertex mapped by T.
  TriangleMesh transformed(const core::Transform& T) const;
  // Concatenation (indices of `other` shifted).
  void append(const TriangleMesh& other);
  // Generalized winding number of the (closed, possibly not watertight) surface around p:
  // ~1 inside, ~0 outside (Jacobson et al. 2013).
  double winding_number(const Eigen::Vector3d& p) const;

  // Closed, outward-oriented primitives centred at the origin (cylinder and its axis along z).
  static TriangleMesh box(const Eigen::Vector3d& size);
  static TriangleMesh cylinder(double radius, double length, int sections = 32);
  static TriangleMesh sphere(double radius, int rings = 12, int sectors = 24);
};

// Reads the v and f records of a Wavefront OBJ file (other records are ignored). Faces may
// use v, v/vt, v//vn, v/vt/vn and negative (relative) indices; polygons are fanned into
// triangles. Throws FileNotFound or std::invalid_argument (naming file and line).
TriangleMesh read_obj(const std::string& path);

// The collision geometry of one link (all its <collision> elements) as a mesh in the link
// frame: meshes from OBJ files (scaled), boxes, cylinders, spheres meshed as above. Returns
// an empty mesh (0 faces) for a link without collision geometry. Throws std::invalid_argument
// for a mesh file that is not OBJ.
TriangleMesh link_collision_mesh(const core::Robot& robot, int link, int cylinder_sections = 32);

}  // namespace pickplan::geometry
