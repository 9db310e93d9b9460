#pragma once
// The points within a radius of others, natively (python/pickplan/omg/grasps/points.py: contact
// patches of grasps from observed points, and antipodal partners).
#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "pickplan/omg/point_sections.hpp"

namespace pickplan::omg {

// The pairs (i, j) with |P_j - P_i| <= radius, i = queries[q] in the order of `queries`, each query's
// j in the place they take in `order` (a permutation of the points; empty: ascending); with `keep`
// (one flag per point), only the j with keep[j]. Ascending is scipy's cKDTree.query_ball_point
// sorted; the tree's `indices` as the order give its unsorted answer (its depth-first leaf order).
// Uniform cells of the radius's size: each query reads its 27 neighbouring cells.
struct RadiusPairs {
  std::vector<long> i, j;
};
RadiusPairs radius_pairs(const RowMatrixXd& points, const std::vector<long>& queries, double radius,
                         const std::vector<std::uint8_t>& keep = {}, const std::vector<long>& order = {});

// The pairs radius_pairs finds that pair up antipodally (antipodal_pair: width >= min_width, margin >=
// cone), in its order, with their margins and widths: an antipodal grasp's contacts and their partners.
struct AntipodalPartners {
  std::vector<long> i, j;
  std::vector<double> margins, widths;
};
AntipodalPartners antipodal_partners(const RowMatrixXd& points, const RowMatrixXd& normals,
                                     const std::vector<long>& queries, double radius,
                                     const std::vector<std::uint8_t>& keep, const std::vector<long>& order,
                                     double min_width, double cone);

}  // namespace pickplan::omg
