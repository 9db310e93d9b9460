#include "pickplan/omg/point_sections.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <string>

namespace pickplan {

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
  std::vector<long> idx;
  std::vector<double> v, u, left, right;
  for (long a = 0; a < ry.cols(); ++a) {
    idx.clear();
    for (long k = 0; k < n; ++k)
      if (std::abs(rx(k, a)) <= s.pad_width / 2 && std::abs(ry(k, a)) <= s.max_width) idx.push_back(k);
    if (idx.size() < 3) continue;
    std::stable_sort(idx.begin(), idx.end(), [&](long p, long q) { return ry(p, a) < ry(q, a); });
    const long m = static_cast<long>(idx.size());
    // the run through 0 (the sampled point): from after the last gap before it to the first gap after
    long first_nonneg = m;
    for (long k = 0; k < m; ++k)
      if (ry(idx[k], a) >= 0.0) {
        first_nonneg = k;
        break;
      }
    long start = 0, stop = m;
    for (long k = 0; k + 1 < m; ++k) {
      if (!(ry(idx[k + 1], a) - ry(idx[k], a) > s.gap)) continue;
      if (k < first_nonneg) start = k + 1;
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
      v.push_back(ry(idx[k], a));
      u.push_back(rx(idx[k], a));
      top = std::max(top, height(idx[k]));
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

}  // namespace pickplan
