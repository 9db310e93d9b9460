#pragma once
// C-Space Iterative Surface Fitting (OMG Sec. III-E, Algorithm 1): refine a grasp configuration
// so the hand's contact surface fits the object, while the hand stays out of the object and the
// arm out of obstacles. f_grasp = f_pml + alpha f_align + gamma (f_hand + beta f_obstacle).
#include <cstdint>
#include <memory>

#include <Eigen/Core>

#include "pickplan/core/robot.hpp"
#include "pickplan/geometry/sdf.hpp"
#include "pickplan/omg/chomp.hpp"

namespace pickplan::omg {

struct IsfSettings {
  double alpha = 0.01;           // normal alignment weight (eq. 13)
  double beta = 0.001;           // arm obstacle weight (eq. 14)
  double gamma = 0.5;            // collision weight (eq. 10)
  double step_size = 0.05;       // eta_grasp: first trial step; shortened until f_grasp decreases
  int max_halvings = 8;          // shortenings of a failed trial step (each at least halves it)
  double length_unit = 0.01;     // distances enter f_pml in this unit (cm), which sets the cost scale
  double hand_epsilon = 0.01;    // padding of the hand-collision cost (m)
  double arm_epsilon = 0.2;      // padding of the arm obstacle cost at g (m), CHOMP's epsilon
  double max_joint_step = 0.05;  // rad: the largest joint change of one step
  std::vector<bool> active;      // joints ISF moves (empty = all)
};

// The support the target rests on (the table): the fingers may touch it, but an ISF step may not press
// them deeper into it than they already were. f_pml pulls the pads towards the object's surface,
// which for a thin object lying on a table is down into the table; the goal set lifts pressing
// fingers until they just touch, and a refinement must not undo that (in PyBullet it jams the
// fingertips against the table while they close).
struct SupportPlane {
  geometry::Vertices
      finger_vertices;  // finger collision-hull vertices in the hand-link frame (fingers as ISF leaves them)
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();  // unit normal; normal . x = offset on the plane
  double offset = 0;
};

struct GraspTerms {
  double pml = 0, align = 0, isf = 0, hand = 0, obstacle = 0, collision = 0, total = 0;
  int matched = 0;  // contact points kept after the repeated-neighbour filter
};

class GraspRefiner {
 public:
  // contacts/normals: hand contact points and inward pad normals in the hand-link frame.
  // hand_sdf: the hand and open fingers as SDF parts, in the hand-link frame. object points/normals:
  // the target's surface samples in the world. body: arm body points for f_obstacle at g.
  GraspRefiner(std::shared_ptr<const core::Robot> robot, int hand_link, geometry::Vertices contacts,
               geometry::Vertices contact_normals, std::shared_ptr<const geometry::SceneSdf> hand_sdf,
               geometry::Vertices object_points, geometry::Vertices object_normals,
               std::shared_ptr<const geometry::SceneSdf> scene, BodyPoints body, std::uint64_t exclude_mask,
               IsfSettings settings);
  ~GraspRefiner();

  GraspTerms cost(const Eigen::VectorXd& q, Eigen::VectorXd* grad) const;
  // One Algorithm-1 step; returns the new configuration and its terms (never worse than q's).
  Eigen::VectorXd step(const Eigen::VectorXd& q, GraspTerms* terms = nullptr) const;
  Eigen::VectorXd refine(const Eigen::VectorXd& q, int iterations, GraspTerms* terms = nullptr) const;

  // The same refiner for the target's surface samples at another place (the target moved: replanning):
  // `motion` (rigid) takes this refiner's object points onto `object_points` (checked on three of them).
  // The k-d tree is shared, queried through the motion; everything else, the support included, is
  // shared or copied.
  std::shared_ptr<GraspRefiner> with_object(geometry::Vertices object_points, geometry::Vertices object_normals,
                                            const core::Transform& motion) const;

  // Set once, before the refiner is shared; an empty finger_vertices removes the support.
  void set_support(SupportPlane support);
  // How far the fingers reach below the support plane at q (m; negative: above it; -inf: no support).
  double support_depth(const Eigen::VectorXd& q) const;

  const IsfSettings& settings() const { return settings_; }

 private:
  struct Index;
  // cost()'s phases: each adds its terms to t and its wrench on the hand (about the hand's origin) to
  // F and tau, or its gradient to gq (null: no gradient).
  void contact_terms(const core::Transform& H, GraspTerms& t, Eigen::Vector3d& F, Eigen::Vector3d& tau) const;
  void hand_collision_terms(const core::Transform& H, GraspTerms& t, Eigen::Vector3d& F, Eigen::Vector3d& tau) const;
  void arm_obstacle_terms(const core::RobotWorkspace& ws, GraspTerms& t, Eigen::VectorXd* gq) const;
  std::shared_ptr<const core::Robot> robot_;
  int hand_;
  geometry::Vertices contacts_, contact_normals_;
  std::shared_ptr<const geometry::SceneSdf> hand_sdf_;
  geometry::Vertices object_points_, object_normals_;
  std::shared_ptr<const geometry::SceneSdf> scene_;
  BodyPoints body_;
  std::uint64_t exclude_mask_;
  IsfSettings settings_;
  SupportPlane support_;
  std::shared_ptr<const Index> index_;  // over the object points as first given; shared by with_object
  core::Transform tree_from_world_;     // world -> the frame of the tree's points
};

}  // namespace pickplan::omg
