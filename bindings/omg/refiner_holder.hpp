#pragma once
// What the Python GraspRefiner holds (bindings/omg/isf.cpp): shared with the OMG loop's binding.
#include <memory>

#include "pickplan/core/robot.hpp"
#include "pickplan/omg/isf.hpp"

namespace pickplan::bind {

using core::Robot;
using omg::GraspRefiner;

struct RefinerHolder {
  std::shared_ptr<Robot> robot;
  std::shared_ptr<GraspRefiner> refiner;
};

}  // namespace pickplan::bind
