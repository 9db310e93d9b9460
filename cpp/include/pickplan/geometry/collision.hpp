#pragma once
// Exact collision checking of a robot against a static scene with FCL (BVH models, OBBRSS).
//
// A CollisionChecker is built once per scene from the robot, one triangle mesh per link (link
// frame), the scene objects (name, mesh in the object frame, pose) and an optional table box.
// It is immutable afterwards: every query takes a CollisionWorkspace (or makes one), so
// queries are reentrant and may run in parallel threads.
//
// Semantics. Link meshes and object meshes are triangle surfaces (FCL BVH); the table and
// primitive objects (CollisionShape from a Primitive) are solids. Two surfaces collide when triangles intersect; with
// `detect_containment` a mesh lying entirely inside a closed mesh (no triangle crossing) also counts, found by a
// generalized-winding-number test. Distances are exact separations between the surfaces
// when apart. In collision they are <= 0 but not a full penetration depth (which would be
// more negative): against the table, minus the largest per-triangle penetration depth (FCL,
// MPR); for two intersecting meshes 0 (FCL has no penetration depth for mesh pairs); for a
// mesh contained in another, minus the gap between the two surfaces.
// in_collision(q) is true when any checked pair collides or is closer than `margin`.
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "pickplan/core/robot.hpp"
#include "pickplan/core/transform.hpp"
#include "pickplan/geometry/mesh.hpp"
#include "pickplan/geometry/primitives.hpp"

namespace pickplan::geometry {

// A mesh with what depends only on it: its FCL bounding-volume hierarchy and bounds, in its own
// frame. Built once per object or link and shared (immutable) by every checker that places it,
// so a new scene of known objects builds no BVH. Or a solid primitive (FCL's box, cylinder,
// sphere: exact, and solid like the table, so a link inside it collides and a penetration
// depth is reported); its mesh() then encloses it (containment probes, bounds of the mesh).
class CollisionShape {
 public:
  // Throws std::invalid_argument ("<what>: ...") for an empty, degenerate or non-finite mesh.
  explicit CollisionShape(TriangleMesh mesh, const std::string& what = "mesh");
  // Throws std::invalid_argument for non-positive or non-finite dimensions.
  explicit CollisionShape(const Primitive& primitive, const std::string& what = "primitive");
  // A convex solid (FCL's Convex: one GJK query per pair instead of a walk down a BVH). `hull`
  // must be convex (a convex hull); the caller vouches for it.
  static std::shared_ptr<CollisionShape> convex(TriangleMesh hull, const std::string& what = "convex");
  bool solid() const { return solid_; }
  // The primitive, when the shape is one (exact distance bounds for culling).
  const Primitive* primitive() const { return has_primitive_ ? &primitive_ : nullptr; }
  ~CollisionShape();
  CollisionShape(const CollisionShape&) = delete;
  CollisionShape& operator=(const CollisionShape&) = delete;

  const TriangleMesh& mesh() const { return mesh_; }
  const Eigen::AlignedBox3d& box() const { return box_; }
  const Eigen::Vector3d& center() const { return center_; }  // of the bounding sphere
  double radius() const { return radius_; }

  struct Bvh;  // FCL's, kept out of this header
  const Bvh& bvh() const { return *bvh_; }

 private:
  TriangleMesh mesh_;
  Eigen::AlignedBox3d box_;
  Eigen::Vector3d center_;
  double radius_ = 0;
  bool solid_ = false;
  bool has_primitive_ = false;
  Primitive primitive_;
  std::unique_ptr<Bvh> bvh_;
  CollisionShape() = default;
};

struct LinkMesh {
  std::string link;                                       // robot link name
  TriangleMesh mesh;                                      // in the link frame (ignored when shape is set)
  std::shared_ptr<const CollisionShape> shape = nullptr;  // prebuilt: reused, not rebuilt
};

struct SceneObject {
  std::string name;                                       // unique, not "table"
  TriangleMesh mesh;                                      // in the object frame (ignored when shape is set)
  core::Transform pose;                                   // object frame in the world
  std::shared_ptr<const CollisionShape> shape = nullptr;  // prebuilt: reused, not rebuilt
};

struct TableBox {
  Eigen::Vector3d size = Eigen::Vector3d::Zero();  // full extents; all zero = no table
  core::Transform pose;                            // box centre in the world
};

struct CollisionSettings {
  // (link, other) pairs never checked; other is an object name, "table" or (self-collision)
  // another link name. Names must exist.
  std::vector<std::pair<std::string, std::string>> allowed_pairs;
  std::vector<std::string> excluded_objects;  // object names (or "table") ignored entirely
  bool self_collision = false;
  // With self_collision: link pairs adjacent in the tree (through links without geometry)
  // and pairs already colliding at the reference configuration are not checked.
  // Empty reference = zero configuration clipped to the joint limits.
  std::vector<double> self_collision_reference;
  double margin = 0.0;             // safety margin (m) for in_collision, >= 0
  bool detect_containment = true;  // a mesh entirely inside another counts as collision
};

enum class OtherKind { Object, Table, Link };

struct ContactInfo {
  std::string link;   // robot link
  std::string other;  // object name, "table" or link name
  OtherKind kind = OtherKind::Object;
  double distance = 0;  // signed: > 0 apart (exact), <= 0 in collision (see the header comment)
  Eigen::Vector3d point_link = Eigen::Vector3d::Zero();   // world; a contact point when colliding
  Eigen::Vector3d point_other = Eigen::Vector3d::Zero();  // world; nearest point otherwise
};

class CollisionChecker;

struct CollisionWorkspace {
  core::RobotWorkspace robot;
  std::vector<std::pair<double, int>> order;  // (lower bound, pair) scratch
  explicit CollisionWorkspace(const CollisionChecker& checker);
};

class CollisionChecker {
 public:
  // Throws std::invalid_argument for empty/degenerate/non-finite meshes, unknown link or
  // object names, duplicate names, a non-positive table size, a negative margin.
  CollisionChecker(const core::Robot& robot, std::vector<LinkMesh> link_meshes, std::vector<SceneObject> objects,
                   const TableBox& table = TableBox{}, CollisionSettings settings = CollisionSettings{});
  ~CollisionChecker();
  CollisionChecker(CollisionChecker&&) noexcept;
  CollisionChecker& operator=(CollisionChecker&&) noexcept;

  const core::Robot& robot() const { return robot_; }
  const CollisionSettings& settings() const { return settings_; }
  int num_pairs() const { return static_cast<int>(pairs_.size()); }  // pairs actually checked
  std::vector<std::pair<std::string, std::string>> checked_pairs() const;
  std::vector<std::string> object_names() const;
  // Moves the object `name` (replanning as the world moves); throws for an unknown name or a pose
  // that is not rigid. Not while another thread checks with this checker.
  void set_object_pose(const std::string& name, const core::Transform& pose);
  // Per robot link: how far its checked geometry reaches from the link frame's origin (0 without any).
  std::vector<double> link_reach() const;

  // q: dof finite values (validated). The workspace overloads do not allocate.
  bool in_collision(const double* q, CollisionWorkspace& ws) const;
  // The same for link poses the caller has put in ws.robot.link_pose (e.g. a free-floating hand
  // placed at a grasp before any IK); only the checked links' poses are read.
  bool in_collision_posed(CollisionWorkspace& ws) const;
  // The least distance over the checked pairs, or `cap` when none is closer than `cap` (pairs whose
  // bounding volumes are `cap` apart are then not measured: a caller needing only "at least cap" pays less).
  double min_distance(const double* q, CollisionWorkspace& ws,
                      double cap = std::numeric_limits<double>::infinity()) const;
  bool in_collision(const Eigen::VectorXd& q) const;
  double min_distance(const Eigen::VectorXd& q) const;
  // Every checked pair in collision or closer than max(margin, within), nearest first.
  std::vector<ContactInfo> contacts(const Eigen::VectorXd& q, double within = 0.0) const;

  // Batches: Q row-major (B, dof); out has B entries. threads <= 0 uses the hardware count.
  void in_collision_batch(const double* Q, long B, bool* out, int threads = 1) const;
  void min_distance_batch(const double* Q, long B, double* out, int threads = 1) const;

  struct Impl;

 private:
  struct Pair {
    int link_geom;  // index into link geometry
    OtherKind kind;
    int other;  // object index, or link geometry index for Link, unused for Table
  };
  void check_q(const double* q) const;
  // The pairs checked: every link against the table and objects not excluded or allowed, and link
  // pairs apart at the self-collision reference (the constructor's last phase).
  void choose_pairs(const std::vector<std::string>& object_names, const std::vector<int>& geom_of_link);
  double pair_lower_bound(const Pair& p, const CollisionWorkspace& ws) const;
  // Signed distance of one pair (fills info when given).
  double pair_distance(const Pair& p, const CollisionWorkspace& ws, bool want_points, ContactInfo* info) const;
  bool pair_collides(const Pair& p, const CollisionWorkspace& ws) const;

  core::Robot robot_;
  CollisionSettings settings_;
  std::unique_ptr<Impl> impl_;
  std::vector<Pair> pairs_;
};

}  // namespace pickplan::geometry
