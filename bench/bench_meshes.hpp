#pragma once
// Meshes for the benchmark: code-built primitives and a binary/ASCII STL reader (YCB meshes).
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <stdexcept>
#include <string>

#include "pickplan/geometry/sdf.hpp"

namespace pickplan::bench {

inline void cylinder_mesh(double r, double h, int sections, geometry::Vertices& V, geometry::Faces& F) {
  V.resize(2 * sections + 2, 3);
  for (int i = 0; i < sections; ++i) {
    const double a = 2 * M_PI * i / sections;
    V.row(i) << r * std::cos(a), r * std::sin(a), -h / 2;
    V.row(sections + i) << r * std::cos(a), r * std::sin(a), h / 2;
  }
  V.row(2 * sections) << 0, 0, -h / 2;
  V.row(2 * sections + 1) << 0, 0, h / 2;
  F.resize(4 * sections, 3);
  for (int i = 0; i < sections; ++i) {
    const int j = (i + 1) % sections;
    F.row(4 * i) << i, j, sections + j;
    F.row(4 * i + 1) << i, sections + j, sections + i;
    F.row(4 * i + 2) << 2 * sections, j, i;
    F.row(4 * i + 3) << 2 * sections + 1, sections + i, sections + j;
  }
}

inline void box_mesh(double x, double y, double z, geometry::Vertices& V, geometry::Faces& F) {
  V.resize(8, 3);
  for (int i = 0; i < 8; ++i) V.row(i) << ((i & 1) ? x : -x) / 2, ((i & 2) ? y : -y) / 2, ((i & 4) ? z : -z) / 2;
  F.resize(12, 3);
  F << 0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5;
}

// Binary STL (triangle soup: three vertices per face).
inline void read_stl(const std::string& path, geometry::Vertices& V, geometry::Faces& F) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot open " + path);
  char header[80];
  std::uint32_t n = 0;
  in.read(header, 80);
  in.read(reinterpret_cast<char*>(&n), 4);
  if (!in || n == 0) throw std::runtime_error("not a binary STL: " + path);
  V.resize(3 * n, 3);
  F.resize(n, 3);
  for (std::uint32_t t = 0; t < n; ++t) {
    float buf[12];
    std::uint16_t attr;
    in.read(reinterpret_cast<char*>(buf), 48);
    in.read(reinterpret_cast<char*>(&attr), 2);
    for (int k = 0; k < 3; ++k) V.row(3 * t + k) << buf[3 + 3 * k], buf[4 + 3 * k], buf[5 + 3 * k];
    F.row(t) << 3 * t, 3 * t + 1, 3 * t + 2;
  }
  if (!in) throw std::runtime_error("truncated STL: " + path);
}

}  // namespace pickplan::bench
