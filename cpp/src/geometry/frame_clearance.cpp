#include "pickplan/geometry/frame_clearance.hpp"

#include <stdexcept>

namespace pickplan::geometry {

std::vector<std::uint8_t> clear_in_frames(const FrameMatrix& frames, const FrameMatrix& points, const SceneSdf& field,
                                          const FrameClearance& s) {
  if (frames.cols() != 16 || points.cols() != 3)
    throw std::invalid_argument("clear in frames: expected (K, 4, 4) frames and (N, 3) points");
  if (!(s.reach >= 0 && std::isfinite(s.threshold) && s.cutoff > 0))
    throw std::invalid_argument("clear in frames: reach >= 0, a finite threshold and cutoff > 0 needed");
  std::vector<std::uint8_t> clear(static_cast<std::size_t>(frames.rows()), 1);
  const double reach2 = s.reach * s.reach;
  for (long k = 0; k < frames.rows(); ++k) {
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
    for (int a = 0; a < 3; ++a) {
      for (int b = 0; b < 3; ++b) R(a, b) = frames(k, 4 * a + b);
      t(a) = frames(k, 4 * a + 3);
    }
    for (long n = 0; n < points.rows(); ++n) {
      Eigen::Vector3d q;
      if (s.inverse) {
        const double dx = points(n, 0) - t(0), dy = points(n, 1) - t(1), dz = points(n, 2) - t(2);
        for (int b = 0; b < 3; ++b) q(b) = dx * R(0, b) + dy * R(1, b) + dz * R(2, b);
        if (q.squaredNorm() >= reach2) continue;
      } else {
        for (int a = 0; a < 3; ++a)
          q(a) = R(a, 0) * points(n, 0) + R(a, 1) * points(n, 1) + R(a, 2) * points(n, 2) + t(a);
      }
      if (!(field.distance(q, nullptr, s.cutoff, s.exclude_mask) > s.threshold)) {
        clear[k] = 0;
        break;
      }
    }
  }
  return clear;
}

}  // namespace pickplan::geometry
