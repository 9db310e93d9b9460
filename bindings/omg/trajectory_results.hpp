#pragma once
// The paper's trajectory metrics as a Python class: bound with CHOMP, returned by the OMG loop too.
#include "../results.hpp"
#include "pickplan/omg/metrics.hpp"

namespace pickplan::bind {

using omg::marked_in_collision;
using omg::TrajectoryMetrics;

inline void bind_trajectory_metrics(py::module_& m) {
  result_class<TrajectoryMetrics>(m, "TrajectoryMetrics", "The success test's measures of a trajectory (Sec. IV-A).")
      .field("smoothness", &TrajectoryMetrics::smoothness)
      .field("collision", &TrajectoryMetrics::collision)
      .field("min_clearance", &TrajectoryMetrics::min_clearance)
      .field("min_table_clearance", &TrajectoryMetrics::min_table_clearance)
      .field("collision_free", &TrajectoryMetrics::collision_free)
      .field("success", &TrajectoryMetrics::success);
  m.def("marked_in_collision", &marked_in_collision, py::arg("metrics"),
        "The metrics of a trajectory an exact check found in collision: neither collision-free nor a success.");
}

}  // namespace pickplan::bind
