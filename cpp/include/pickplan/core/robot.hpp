#pragma once
// Kinematic tree loaded from URDF (urdfdom): immutable after loading. Per-call scratch
// (link poses, joint axes) lives in a RobotWorkspace so hot loops never allocate.
#include <string>
#include <vector>

#include <Eigen/Core>

#include "pickplan/core/transform.hpp"

namespace pickplan::core {

enum class JointType { Fixed, Revolute, Continuous, Prismatic };

struct CollisionGeometry {
  enum class Kind { Mesh, Box, Cylinder, Sphere };
  Kind kind = Kind::Mesh;
  std::string mesh_path;                            // absolute, for Kind::Mesh
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();  // mesh scale
  Eigen::Vector3d size = Eigen::Vector3d::Zero();   // box: xyz; cylinder: (radius, length, 0); sphere: (radius, 0, 0)
  Transform origin;                                 // geometry frame in the link frame
};

struct Mimic {
  int source_q = -1;  // configuration index that drives this joint, -1 when not a mimic joint
  double multiplier = 1.0;
  double offset = 0.0;
};

struct Link {
  std::string name;
  int parent = -1;         // index of the parent link, -1 for the root
  std::string joint_name;  // joint connecting the parent to this link ("" for the root)
  JointType joint_type = JointType::Fixed;
  Transform joint_origin;                           // joint frame in the parent link frame
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // unit joint axis in the joint frame
  bool axis_is_z = true;                            // revolute about +z (every Panda joint): a cheaper rotation in FK
  int q_index = -1;                                 // configuration index of the joint, -1 for fixed joints
  Mimic mimic;
  std::vector<CollisionGeometry> collisions;
};

class Robot;

struct RobotWorkspace {
  std::vector<Transform> link_pose;         // world pose of every link frame
  std::vector<Eigen::Vector3d> axis_world;  // world joint axis of every link (set by FK, read by Jacobians)
  explicit RobotWorkspace(const Robot& robot);
};

class Robot {
 public:
  // Loads a URDF file; package:// URIs are searched in package_dirs, then in the URDF's
  // folder and its ancestors. Throws FileNotFound (URDF or a collision mesh missing) or
  // std::invalid_argument (malformed URDF, unsupported joint type).
  static Robot from_urdf_file(const std::string& path, const std::vector<std::string>& package_dirs = {});
  static Robot from_urdf_string(const std::string& xml, const std::string& base_dir,
                                const std::vector<std::string>& package_dirs = {},
                                const std::string& source_name = "<string>");

  // A copy of this robot whose root link sits at `base` in the world.
  Robot with_base(const Transform& base) const;
  // A copy with one more link, `name`, fixed to `parent` at `origin` (its frame in the parent's):
  // what the robot holds (a grasped object) moves with the hand as part of the robot, so body
  // points, Jacobians and collision meshes on it need nothing new. Appended last (parents come
  // first), so the existing links keep their indices. Throws for a taken name, an unknown parent
  // or a non-rigid origin.
  Robot with_attached_link(const std::string& name, const std::string& parent, const Transform& origin) const;

  int dof() const { return static_cast<int>(joint_names_.size()); }
  int num_links() const { return static_cast<int>(links_.size()); }
  const std::string& name() const { return name_; }
  const std::vector<Link>& links() const { return links_; }
  const Link& link(int i) const { return links_.at(i); }
  const std::vector<std::string>& link_names() const { return link_names_; }
  const std::vector<std::string>& joint_names() const { return joint_names_; }  // movable joints, q order
  const Eigen::VectorXd& lower_limits() const { return lower_; }
  const Eigen::VectorXd& upper_limits() const { return upper_; }
  const Eigen::VectorXd& velocity_limits() const { return velocity_; }
  const Transform& base() const { return base_; }
  // Index of the link whose joint is configuration entry q (the joint's child link).
  int link_of_q(int q) const { return q_link_.at(q); }
  // True when configuration entry q moves link (q's joint is on the chain to it).
  bool moves(int q, int link) const { return chain_mask_[link * dof() + q] != 0; }

  int link_index(const std::string& name) const;            // throws std::invalid_argument naming the links
  void check_configuration(const double* q, long n) const;  // size and finiteness

  // Fills ws.link_pose for configuration q (size dof, not validated: hot path).
  void forward_kinematics(const double* q, RobotWorkspace& ws) const { forward_kinematics(q, ws, num_links() - 1); }
  // Links 0..last only (links are stored parents first, so these include every ancestor of
  // `last`): what IK needs for its tip, without the links past it (the fingers).
  void forward_kinematics(const double* q, RobotWorkspace& ws, int last) const;
  // 6 x dof Jacobian (linear rows 0-2, angular rows 3-5, world frame) of a point fixed on a
  // link, given in the link frame. Uses poses already in ws. J must be 6 x dof.
  void point_jacobian(const RobotWorkspace& ws, int link, const Eigen::Vector3d& point_local,
                      Eigen::Ref<Eigen::Matrix<double, 6, Eigen::Dynamic>> J) const;
  // 3 x dof linear Jacobian of a world point x rigidly attached to `link` (cheaper: no local transform).
  void position_jacobian_world(const RobotWorkspace& ws, int link, const Eigen::Vector3d& x_world,
                               Eigen::Ref<Eigen::Matrix<double, 3, Eigen::Dynamic>> J) const;
  // out += sum_i J(x_i)^T f_i over forces f_i at world points x_i on `link`, given only their
  // sum F and world moment M = sum_i x_i x f_i: joint j gets a_j . (M - p_j x F) (revolute) or
  // a_j . F (prismatic). The CHOMP gradient pull-back, one chain walk per link and waypoint.
  void add_wrench_jacobian_transpose(const RobotWorkspace& ws, int link, const Eigen::Vector3d& force,
                                     const Eigen::Vector3d& moment, double* out) const;

 private:
  void finalize();  // builds names, limits, chains after links_ are filled

  std::string name_;
  Transform base_;
  std::vector<Link> links_;  // topological order: parents before children
  std::vector<std::string> link_names_;
  std::vector<std::string> joint_names_;
  std::vector<int> q_link_;
  std::vector<char> chain_mask_;  // num_links x dof
  Eigen::VectorXd lower_, upper_, velocity_;
};

}  // namespace pickplan::core
