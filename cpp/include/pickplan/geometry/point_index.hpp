#pragma once
// The nearest of a fixed set of points (rows of a row-major N x 3 matrix) by a k-d tree (nanoflann):
// C-Space ISF's contact matching and the observed target's distance grid share it.
#include <cstddef>

#include <nanoflann.hpp>

#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {

class PointIndex {
 public:
  // `points` must outlive the index and not change (the tree refers to it).
  explicit PointIndex(const Vertices* points)
      : cloud_{points}, tree_(3, cloud_, nanoflann::KDTreeSingleIndexAdaptorParams(10)) {
    tree_.buildIndex();
  }
  // The nearest point's row and its squared distance from q (x, y, z).
  void nearest(const double* q, std::size_t* index, double* squared_distance) const {
    nanoflann::KNNResultSet<double, std::size_t> res(1);
    res.init(index, squared_distance);
    tree_.findNeighbors(res, q, nanoflann::SearchParams(10));
  }
  // The same, searching only closer than sqrt(bound2) (a known upper bound of the nearest distance
  // prunes the tree); false, and nothing written, when no point is that close.
  bool nearest_within(const double* q, double bound2, std::size_t* index, double* squared_distance) const {
    nanoflann::KNNResultSet<double, std::size_t> res(1);
    std::size_t i = 0;
    double d2 = 0;
    res.init(&i, &d2);
    d2 = bound2;  // the result set's worst distance: only closer points are taken
    tree_.findNeighbors(res, q, nanoflann::SearchParams(10));
    if (res.size() == 0) return false;
    *index = i, *squared_distance = d2;
    return true;
  }

 private:
  struct Cloud {
    const Vertices* pts;
    std::size_t kdtree_get_point_count() const { return static_cast<std::size_t>(pts->rows()); }
    double kdtree_get_pt(std::size_t i, std::size_t d) const {
      return (*pts)(static_cast<Eigen::Index>(i), static_cast<Eigen::Index>(d));
    }
    template <class BBOX>
    bool kdtree_get_bbox(BBOX&) const {
      return false;
    }
  };
  using Tree = nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, Cloud>, Cloud, 3>;
  Cloud cloud_;
  Tree tree_;
};

}  // namespace pickplan::geometry
