#pragma once
// Whether sample points keep clear of a scene's field in many frames at once, stopping at a frame's
// first point too close: the open hand against observed points (python/pickplan/omg/grasps/points.py),
// the hand's samples against a fused depth field.
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {

using FrameMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// How sample points are tested in each frame: inverse, the points are world points taken into the
// frame (q = R^T (p - t)) and only those with |q| < reach are read (the open hand's bound); else the
// points are in the frame and go to the world (q = R p + t). A frame is clear when every point read
// has field.distance(q, cutoff, exclude_mask) > threshold.
struct FrameClearance {
  bool inverse = true;
  double reach = 0.15;
  double threshold = 0.0;
  double cutoff = 0.05;
  std::uint64_t exclude_mask = 0;
};

// frames: K row-major 4 x 4 poses, one per row; points (N, 3). One flag per frame.
std::vector<std::uint8_t> clear_in_frames(const FrameMatrix& frames, const FrameMatrix& points, const SceneSdf& field,
                                          const FrameClearance& settings);

}  // namespace pickplan::geometry
