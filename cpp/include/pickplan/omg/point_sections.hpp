#pragma once
// Grasps from observed points (python/pickplan/omg/grasps/points.py): the local sections of grasps
// from above, the loop over seeded footprint points and closing directions done natively. Per
// closing direction, the points in the band the pads sweep give the part the pads close on (the run
// through the sampled point with no gap wider than `gap`), its width between the `trim` quantiles
// (numpy's default linear quantile, to the last bit) and whether both of its ends face the pads.
// And the points each candidate's pads would hold (its score's pad fill).
#include <vector>

#include <Eigen/Core>

namespace pickplan::omg {

using RowMatrixXd = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

struct SectionSettings {
  double pad_width = 0.02;   // m across a pad: the band is half of it on either side
  double max_width = 0.08;   // m: the band reaches this far along the closing direction either side
  double gap = 0.006;        // m: a wider gap between sorted points ends the part
  double trim = 0.01;        // quantile at each end of the width (noise)
  double min_width = 0.004;  // m: the width must lie in [min_width, fit_width]
  double fit_width = 0.074;
  double face_tolerance = 0.0036;  // m the two halves' ends may differ (tan(max_face_turn) * pad_width / 2)
  void validate() const;           // throws std::invalid_argument
};

struct LocalSection {
  int yaw = 0;                            // column of ry / rx
  double lo = 0, hi = 0;                  // the trim quantiles across the pads
  double across_min = 0, across_max = 0;  // extent along the pads' width (rx)
  double top = 0;                         // the highest point of the part (height above the support)
};

// ry, rx: (N, A) the points relative to the sampled one, across the pads and along their width, per
// closing direction; height: (N,). The sections that pass, in column order.
std::vector<LocalSection> local_sections(const RowMatrixXd& ry, const RowMatrixXd& rx, const Eigen::VectorXd& height,
                                         const SectionSettings& settings);

// Per grasp frame (frames: K row-major 4 x 4 matrices, one per row), how many `points` lie in the
// box |q| < half.row(k) of the frame's axes about its origin (q = R^T (p - origin)).
Eigen::VectorXi points_in_frames(const RowMatrixXd& frames, const RowMatrixXd& points, const RowMatrixXd& half);

// Whether points a and b (unit normals) pair up antipodally: the width w = |P_b - P_a| >= min_width and,
// with the axis x = (P_b - P_a) / w, the margin min(-x . N_a, N_b . x) >= cone (margin and width set
// when it passes).
bool antipodal_pair(const RowMatrixXd& points, const RowMatrixXd& normals, long a, long b, double min_width,
                    double cone, double* margin, double* width);

// numpy's default (linear) quantile of the sorted values v[0..n), to the last bit.
double sorted_quantile(const double* v, long n, double q);

}  // namespace pickplan::omg
