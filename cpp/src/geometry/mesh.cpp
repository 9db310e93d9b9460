#include "pickplan/geometry/mesh.hpp"

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "pickplan/core/errors.hpp"

namespace pickplan::geometry {

void TriangleMesh::validate(const std::string& what) const {
  if (num_faces() == 0 || num_vertices() == 0)
    throw std::invalid_argument(what + ": empty mesh (" + std::to_string(num_vertices()) + " vertices, " +
                                std::to_string(num_faces()) + " faces)");
  core::require_finite(what.c_str(), vertices.data(), static_cast<long>(vertices.size()));
  double area = 0.0;
  for (int f = 0; f < num_faces(); ++f) {
    for (int k = 0; k < 3; ++k) {
      const int i = faces(f, k);
      if (i < 0 || i >= num_vertices())
        throw std::invalid_argument(what + ": face " + std::to_string(f) + " uses vertex " + std::to_string(i) +
                                    ", out of range [0, " + std::to_string(num_vertices()) + ")");
    }
    const Eigen::Vector3d a = vertices.row(faces(f, 0)), b = vertices.row(faces(f, 1)), c = vertices.row(faces(f, 2));
    area += 0.5 * (b - a).cross(c - a).norm();
  }
  if (!(area > 0.0)) throw std::invalid_argument(what + ": degenerate mesh (all faces have zero area)");
}

TriangleMesh TriangleMesh::transformed(const core::Transform& T) const {
  TriangleMesh out = *this;
  for (int i = 0; i < num_vertices(); ++i) out.vertices.row(i) = T.apply(vertices.row(i).transpose()).transpose();
  return out;
}

// Solid angles by Van Oosterom & Strackee.
double TriangleMesh::winding_number(const Eigen::Vector3d& p) const {
  const TriangleMesh& m = *this;
  double sum = 0.0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)).transpose() - p;
    const Eigen::Vector3d b = m.vertices.row(m.faces(f, 1)).transpose() - p;
    const Eigen::Vector3d c = m.vertices.row(m.faces(f, 2)).transpose() - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double num = a.dot(b.cross(c));
    const double den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    sum += 2.0 * std::atan2(num, den);
  }
  return sum / (4.0 * M_PI);
}

void TriangleMesh::append(const TriangleMesh& other) {
  const int nv = num_vertices(), nf = num_faces();
  vertices.conservativeResize(nv + other.num_vertices(), 3);
  faces.conservativeResize(nf + other.num_faces(), 3);
  if (other.num_vertices()) vertices.bottomRows(other.num_vertices()) = other.vertices;
  if (other.num_faces()) faces.bottomRows(other.num_faces()) = other.faces.array() + nv;
}

TriangleMesh TriangleMesh::box(const Eigen::Vector3d& size) {
  if (!(size.array() > 0).all() || !size.allFinite())
    throw std::invalid_argument("box: sizes must be positive and finite");
  TriangleMesh m;
  m.vertices.resize(8, 3);
  for (int i = 0; i < 8; ++i)
    m.vertices.row(i) << (i & 1 ? 0.5 : -0.5) * size.x(), (i & 2 ? 0.5 : -0.5) * size.y(),
        (i & 4 ? 0.5 : -0.5) * size.z();
  m.faces.resize(12, 3);
  m.faces << 0, 2, 1, 1, 2, 3,  // -z
      4, 5, 6, 5, 7, 6,         // +z
      0, 1, 4, 1, 5, 4,         // -y
      2, 6, 3, 3, 6, 7,         // +y
      0, 4, 2, 2, 4, 6,         // -x
      1, 3, 5, 3, 7, 5;         // +x
  return m;
}

TriangleMesh TriangleMesh::cylinder(double radius, double length, int sections) {
  if (!(radius > 0) || !(length > 0) || !std::isfinite(radius) || !std::isfinite(length) || sections < 3)
    throw std::invalid_argument("cylinder: radius and length must be positive and finite, sections >= 3");
  TriangleMesh m;
  const int n = sections;
  m.vertices.resize(2 * n + 2, 3);
  for (int i = 0; i < n; ++i) {
    const double a = 2.0 * M_PI * i / n;
    m.vertices.row(i) << radius * std::cos(a), radius * std::sin(a), -0.5 * length;
    m.vertices.row(n + i) << radius * std::cos(a), radius * std::sin(a), 0.5 * length;
  }
  m.vertices.row(2 * n) << 0, 0, -0.5 * length;
  m.vertices.row(2 * n + 1) << 0, 0, 0.5 * length;
  m.faces.resize(4 * n, 3);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    m.faces.row(4 * i + 0) << i, j, n + j;
    m.faces.row(4 * i + 1) << i, n + j, n + i;
    m.faces.row(4 * i + 2) << 2 * n, j, i;
    m.faces.row(4 * i + 3) << 2 * n + 1, n + i, n + j;
  }
  return m;
}

TriangleMesh TriangleMesh::sphere(double radius, int rings, int sectors) {
  if (!(radius > 0) || !std::isfinite(radius) || rings < 2 || sectors < 3)
    throw std::invalid_argument("sphere: radius must be positive and finite, rings >= 2, sectors >= 3");
  TriangleMesh m;
  const int inner = (rings - 1) * sectors;
  m.vertices.resize(inner + 2, 3);
  for (int r = 1; r < rings; ++r) {
    const double th = M_PI * r / rings;
    for (int s = 0; s < sectors; ++s) {
      const double ph = 2.0 * M_PI * s / sectors;
      m.vertices.row((r - 1) * sectors + s) << radius * std::sin(th) * std::cos(ph),
          radius * std::sin(th) * std::sin(ph), radius * std::cos(th);
    }
  }
  const int top = inner, bottom = inner + 1;
  m.vertices.row(top) << 0, 0, radius;
  m.vertices.row(bottom) << 0, 0, -radius;
  std::vector<Eigen::Vector3i> f;
  for (int s = 0; s < sectors; ++s) {
    const int t = (s + 1) % sectors;
    f.emplace_back(top, s, t);
    f.emplace_back(bottom, (rings - 2) * sectors + t, (rings - 2) * sectors + s);
    for (int r = 0; r + 1 < rings - 1; ++r) {
      const int a = r * sectors + s, b = r * sectors + t, c = (r + 1) * sectors + s, d = (r + 1) * sectors + t;
      f.emplace_back(a, c, d);
      f.emplace_back(a, d, b);
    }
  }
  m.faces.resize(static_cast<int>(f.size()), 3);
  for (size_t i = 0; i < f.size(); ++i) m.faces.row(static_cast<int>(i)) = f[i].transpose();
  return m;
}

TriangleMesh read_obj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw core::FileNotFound("OBJ file not found: '" + path + "'");
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> f;
  std::string line;
  int lineno = 0;
  auto fail = [&](const std::string& why) {
    throw std::invalid_argument("malformed OBJ '" + path + "' line " + std::to_string(lineno) + ": " + why);
  };
  while (std::getline(in, line)) {
    ++lineno;
    std::istringstream ss(line);
    std::string tag;
    if (!(ss >> tag)) continue;
    if (tag == "v") {
      Eigen::Vector3d p;
      if (!(ss >> p.x() >> p.y() >> p.z())) fail("expected 3 coordinates after 'v'");
      v.push_back(p);
    } else if (tag == "f") {
      std::vector<int> idx;
      for (std::string tok; ss >> tok;) {
        const std::string first = tok.substr(0, tok.find('/'));
        int i = 0;
        try {
          size_t used = 0;
          i = std::stoi(first, &used);
          if (used != first.size()) throw std::invalid_argument("");
        } catch (const std::exception&) {
          fail("bad vertex reference '" + tok + "'");
        }
        if (i == 0) fail("vertex index 0 (OBJ indices start at 1)");
        const int resolved = i > 0 ? i - 1 : static_cast<int>(v.size()) + i;
        if (resolved < 0 || resolved >= static_cast<int>(v.size()))
          fail("vertex index " + std::to_string(i) + " refers to a vertex not yet defined");
        idx.push_back(resolved);
      }
      if (idx.size() < 3) fail("a face needs at least 3 vertices");
      for (size_t k = 1; k + 1 < idx.size(); ++k) f.emplace_back(idx[0], idx[k], idx[k + 1]);
    }
  }
  TriangleMesh m;
  m.vertices.resize(static_cast<int>(v.size()), 3);
  for (size_t i = 0; i < v.size(); ++i) m.vertices.row(static_cast<int>(i)) = v[i].transpose();
  m.faces.resize(static_cast<int>(f.size()), 3);
  for (size_t i = 0; i < f.size(); ++i) m.faces.row(static_cast<int>(i)) = f[i].transpose();
  if (m.num_faces() == 0) throw std::invalid_argument("OBJ '" + path + "' has no faces");
  return m;
}

TriangleMesh link_collision_mesh(const core::Robot& robot, int link, int cylinder_sections) {
  TriangleMesh out;
  out.vertices.resize(0, 3);
  out.faces.resize(0, 3);
  for (const auto& g : robot.link(link).collisions) {
    TriangleMesh part;
    switch (g.kind) {
      case core::CollisionGeometry::Kind::Mesh: {
        std::string ext = std::filesystem::path(g.mesh_path).extension().string();
        for (auto& c : ext) c = static_cast<char>(std::tolower(c));
        if (ext != ".obj")
          throw std::invalid_argument(
              "link '" + robot.link(link).name + "': collision mesh '" + g.mesh_path +
              "' is not an OBJ file (the native reader handles OBJ only; pass meshes from Python)");
        part = read_obj(g.mesh_path);
        for (int i = 0; i < part.num_vertices(); ++i)
          part.vertices.row(i) = part.vertices.row(i).cwiseProduct(g.scale.transpose());
        break;
      }
      case core::CollisionGeometry::Kind::Box:
        part = TriangleMesh::box(g.size);
        break;
      case core::CollisionGeometry::Kind::Cylinder:
        part = TriangleMesh::cylinder(g.size.x(), g.size.y(), cylinder_sections);
        break;
      case core::CollisionGeometry::Kind::Sphere:
        part = TriangleMesh::sphere(g.size.x());
        break;
    }
    out.append(part.transformed(g.origin));
  }
  return out;
}

}  // namespace pickplan::geometry
