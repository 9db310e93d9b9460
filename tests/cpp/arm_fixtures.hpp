#pragma once
// Small robots written in code for the C++ tests of CHOMP, ISF, goal sets, metrics and STOMP, and a
// check that misuse throws std::invalid_argument naming the problem.
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "pickplan/core/robot.hpp"

namespace pickplan::test {

// A hand that moves freely: prismatic x, y, z, then revolute z, y, x about the same point, so the
// hand origin sits exactly at (q0, q1, q2) whatever the rotation. Its collision geometry is a palm
// box (kPalmSize) centred kPalmCenter behind the origin (hand -z): the hand approaches along +z.
inline const Eigen::Vector3d kPalmSize(0.1, 0.1, 0.04);
inline const Eigen::Vector3d kPalmCenter(0, 0, -0.05);
inline const char* kFloatingHandUrdf = R"(<?xml version="1.0"?>
<robot name="floating_hand">
  <link name="world"/><link name="px"/><link name="py"/><link name="pz"/><link name="rz"/><link name="ry"/>
  <link name="hand"><collision><origin xyz="0 0 -0.05"/><geometry><box size="0.1 0.1 0.04"/></geometry></collision></link>
  <joint name="x" type="prismatic"><parent link="world"/><child link="px"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="y" type="prismatic"><parent link="px"/><child link="py"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
  <joint name="z" type="prismatic"><parent link="py"/><child link="pz"/><axis xyz="0 0 1"/>
    <limit lower="-0.5" upper="1" effort="1" velocity="1"/></joint>
  <joint name="yaw" type="revolute"><parent link="pz"/><child link="rz"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="pitch" type="revolute"><parent link="rz"/><child link="ry"/><axis xyz="0 1 0"/>
    <limit lower="-1.4" upper="1.4" effort="1" velocity="1"/></joint>
  <joint name="roll" type="revolute"><parent link="ry"/><child link="hand"/><axis xyz="1 0 0"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>)";

// A mobile base (x, y, yaw: the first three DOFs, as pick-up on the move needs) carrying a planar
// two-link arm: shoulder 0.3 m above the base, links 0.5 m and 0.4 m, both joints about z.
inline const char* kMobileTwoLinkUrdf = R"(<?xml version="1.0"?>
<robot name="mobile_two_link">
  <link name="world"/><link name="bx"/><link name="by"/><link name="base"/><link name="upper"/><link name="fore"/>
  <link name="tool"/>
  <joint name="base_x" type="prismatic"><parent link="world"/><child link="bx"/><axis xyz="1 0 0"/>
    <limit lower="-10" upper="10" effort="1" velocity="2"/></joint>
  <joint name="base_y" type="prismatic"><parent link="bx"/><child link="by"/><axis xyz="0 1 0"/>
    <limit lower="-10" upper="10" effort="1" velocity="2"/></joint>
  <joint name="base_yaw" type="continuous"><parent link="by"/><child link="base"/><axis xyz="0 0 1"/></joint>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.3"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0.5 0 0"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="1" velocity="2"/></joint>
  <joint name="tool_mount" type="fixed"><parent link="fore"/><child link="tool"/><origin xyz="0.4 0 0"/></joint>
</robot>)";

inline std::shared_ptr<core::Robot> floating_hand() {
  return std::make_shared<core::Robot>(core::Robot::from_urdf_string(kFloatingHandUrdf, ".", {}, "floating_hand"));
}

inline std::shared_ptr<core::Robot> mobile_two_link() {
  return std::make_shared<core::Robot>(core::Robot::from_urdf_string(kMobileTwoLinkUrdf, ".", {}, "mobile_two_link"));
}

// Runs f and expects std::invalid_argument whose message contains `fragment`.
template <class F>
void expect_invalid_argument(F&& f, const std::string& fragment) {
  try {
    f();
    ADD_FAILURE() << "no exception; expected std::invalid_argument containing \"" << fragment << "\"";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << "message: " << e.what();
  }
}

}  // namespace pickplan::test
