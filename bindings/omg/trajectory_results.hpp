#pragma once
// Trajectories and the paper's metrics as Python values: shared by the CHOMP and OMG-loop bindings.
#include "../common.hpp"
#include "pickplan/omg/chomp.hpp"
#include "pickplan/omg/metrics.hpp"

namespace pickplan::bind {

using omg::Trajectory;
using omg::TrajectoryMetrics;

inline py::array_t<double> to_array(const Trajectory& t) {
  py::array_t<double> out({t.rows(), t.cols()});
  Eigen::Map<Trajectory>(out.mutable_data(), t.rows(), t.cols()) = t;
  return out;
}

inline py::dict metrics_dict(const TrajectoryMetrics& mt) {
  py::dict d;
  d["smoothness"] = mt.smoothness;
  d["collision"] = mt.collision;
  d["min_clearance"] = mt.min_clearance;
  d["min_table_clearance"] = mt.min_table_clearance;
  d["collision_free"] = mt.collision_free;
  d["success"] = mt.success;
  return d;
}

}  // namespace pickplan::bind
