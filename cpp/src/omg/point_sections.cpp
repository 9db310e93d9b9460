#include "pickplan/omg/point_sections.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace pickplan::omg {

void SectionSettings::validate() const {
  const double all[] = {pad_width, max_width, gap, trim, min_width, fit_width, face_tolerance};
  for (double x : all)
    if (!std::isfinite(x) || x < 0) throw std::invalid_argument("local sections: settings must be finite and >= 0");
  if (trim >= 0.5) throw std::invalid_argument("local sections: trim must be < 0.5, got " + std::to_string(trim));
}

double sorted_quantile(const double* v, long n, double q) {
  const double at = static_cast<double>(n - 1) * q;
  const double lo = std::floor(at), t = at - lo;
  const long i = std::min(static_cast<long>(lo), n - 1), j = std::min(i + 1, n - 1);
  const double a = v[i], b = v[j], diff = b - a;
  return t >= 0.5 ? b - diff * (1 - t) : a + diff * t;  // numpy's _lerp
}

namespace {

// Whether both ends of the section (sorted values v, along the pads' width u) lie within the
// tolerance in the pads' two halves (u < 0 and u >= 0), each half holding at least two points.
bool faces_the_pads(const std::vector<double>& v, const std::vector<double>& u, const SectionSettings& s,
                    std::vector<double>* left, std::vector<double>* right) {
  left->clear();
  right->clear();
  for (std::size_t k = 0; k < v.size(); ++k) (u[k] < 0 ? left : right)->push_back(v[k]);
  if (left->size() < 2 || right->size() < 2) return false;
  const long nl = static_cast<long>(left->size()), nr = static_cast<long>(right->size());
  const double d0 = sorted_quantile(left->data(), nl, s.trim) - sorted_quantile(right->data(), nr, s.trim);
  const double d1 = sorted_quantile(left->data(), nl, 1.0 - s.trim) - sorted_quantile(right->data(), nr, 1.0 - s.trim);
  return std::max(std::abs(d0), std::abs(d1)) <= s.face_tolerance;
}

}  // namespace

std::vector<LocalSection> local_sections(const RowMatrixXd& ry, const RowMatrixXd& rx, const Eigen::VectorXd& height,
                                         const SectionSettings& s) {
  s.validate();
  const long n = ry.rows();
  if (rx.rows() != n || rx.cols() != ry.cols() || height.size() != n)
    throw std::invalid_argument("local sections: expected ry, rx of one shape (N, A) and N heights, got (" +
                                std::to_string(ry.rows()) + ", " + std::to_string(ry.cols()) + "), (" +
                                std::to_string(rx.rows()) + ", " + std::to_string(rx.cols()) + "), " +
                                std::to_string(height.size()));
  std::vector<LocalSection> out;
  struct Banded {
    double along, across, height;
    long k;
  };
  std::vector<Banded> band;
  std::vector<double> v, u, left, right;
  for (long a = 0; a < ry.cols(); ++a) {
    band.clear();
    for (long k = 0; k < n; ++k)
      if (std::abs(rx(k, a)) <= s.pad_width / 2 && std::abs(ry(k, a)) <= s.max_width)
        band.push_back({ry(k, a), rx(k, a), height(k), k});
    if (band.size() < 3) continue;
    // sorted along the closing direction, ties in point order (a stable sort's order)
    std::sort(band.begin(), band.end(),
              [](const Banded& p, const Banded& q) { return p.along < q.along || (p.along == q.along && p.k < q.k); });
    const long m = static_cast<long>(band.size());
    // the run through 0 (the sampled point): from after the last gap before it to the first gap after
    long first_nonneg = m;
    for (long k = 0; k < m; ++k)
      if (band[k].along >= 0.0) {
        first_nonneg = k;
        break;
      }
    long start = 0, stop = m;
    for (long k = 0; k + 1 < m; ++k) {
      if (!(band[k + 1].along - band[k].along > s.gap)) continue;
      if (k < first_nonneg)
        start = k + 1;
      else {
        stop = k + 1;
        break;
      }
    }
    if (stop - start < 3) continue;
    v.clear();
    u.clear();
    double top = -INFINITY;
    for (long k = start; k < stop; ++k) {
      v.push_back(band[k].along);
      u.push_back(band[k].across);
      top = std::max(top, band[k].height);
    }
    const long len = stop - start;
    LocalSection sec;
    sec.yaw = static_cast<int>(a);
    sec.lo = sorted_quantile(v.data(), len, s.trim);
    sec.hi = sorted_quantile(v.data(), len, 1.0 - s.trim);
    if (!(s.min_width <= sec.hi - sec.lo && sec.hi - sec.lo <= s.fit_width)) continue;
    if (!faces_the_pads(v, u, s, &left, &right)) continue;
    sec.across_min = *std::min_element(u.begin(), u.end());
    sec.across_max = *std::max_element(u.begin(), u.end());
    sec.top = top;
    out.push_back(sec);
  }
  return out;
}

bool antipodal_pair(const RowMatrixXd& points, const RowMatrixXd& normals, long a, long b, double min_width,
                    double cone, double* margin, double* width) {
  const double dx = points(b, 0) - points(a, 0), dy = points(b, 1) - points(a, 1), dz = points(b, 2) - points(a, 2);
  // facing away from either normal, the margin is negative (a positive cone is missed): no square root
  if (cone > 0 && (dx * normals(a, 0) + dy * normals(a, 1) + dz * normals(a, 2) >= 0 ||
                   dx * normals(b, 0) + dy * normals(b, 1) + dz * normals(b, 2) <= 0))
    return false;
  const double w = std::sqrt(dx * dx + dy * dy + dz * dz);  // numpy's norm: the squares summed in order
  if (!(w >= min_width)) return false;
  const double ax = dx / w, ay = dy / w, az = dz / w;
  const double from = -(ax * normals(a, 0) + ay * normals(a, 1) + az * normals(a, 2));
  const double to = normals(b, 0) * ax + normals(b, 1) * ay + normals(b, 2) * az;
  *margin = std::min(from, to);
  *width = w;
  return *margin >= cone;
}

Eigen::VectorXi points_in_frames(const RowMatrixXd& frames, const RowMatrixXd& points, const RowMatrixXd& half) {
  if (frames.cols() != 16 || points.cols() != 3 || half.cols() != 3 || half.rows() != frames.rows())
    throw std::invalid_argument("points in frames: expected (K, 16) frames, (N, 3) points and (K, 3) half sizes");
  Eigen::VectorXi counts = Eigen::VectorXi::Zero(frames.rows());
  for (long k = 0; k < frames.rows(); ++k) {
    const double* T = frames.row(k).data();  // row-major 4 x 4: axes in columns 0..2, origin in column 3
    const double hx = half(k, 0), hy = half(k, 1), hz = half(k, 2), r2 = hx * hx + hy * hy + hz * hz;
    int c = 0;
    for (long i = 0; i < points.rows(); ++i) {
      const double dx = points(i, 0) - T[3], dy = points(i, 1) - T[7], dz = points(i, 2) - T[11];
      if (dx * dx + dy * dy + dz * dz > r2) continue;  // outside the box's circumscribed sphere
      const double qx = dx * T[0] + dy * T[4] + dz * T[8], qy = dx * T[1] + dy * T[5] + dz * T[9],
                   qz = dx * T[2] + dy * T[6] + dz * T[10];
      c += std::abs(qx) < hx && std::abs(qy) < hy && std::abs(qz) < hz;
    }
    counts(k) = c;
  }
  return counts;
}

}  // namespace pickplan::omg
