// FCL collision checker against closed-form geometry; mesh primitives and the OBJ reader.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <random>

#include <gtest/gtest.h>

#include "pickplan/core/errors.hpp"
#include "pickplan/geometry/collision.hpp"
#include "pickplan/geometry/mesh.hpp"

using namespace pickplan::core;
using namespace pickplan::geometry;

namespace {

const std::string kData = PICKPLAN_TEST_DATA_DIR;

double volume(const TriangleMesh& m) {  // divergence theorem: positive for outward faces
  double v = 0;
  for (int f = 0; f < m.num_faces(); ++f) {
    const Eigen::Vector3d a = m.vertices.row(m.faces(f, 0)), b = m.vertices.row(m.faces(f, 1)),
                          c = m.vertices.row(m.faces(f, 2));
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

Transform translation(double x, double y, double z) {
  Transform T;
  T.p = Eigen::Vector3d(x, y, z);
  return T;
}

Transform rot_z(double a, const Eigen::Vector3d& p) {
  Transform T;
  T.R = axis_angle(Eigen::Vector3d::UnitZ(), a);
  T.p = p;
  return T;
}

Robot mixed_arm() { return Robot::from_urdf_file(kData + "/mixed_arm.urdf"); }

std::vector<LinkMesh> meshes_of(const Robot& r) {
  std::vector<LinkMesh> out;
  for (int l = 0; l < r.num_links(); ++l) {
    TriangleMesh m = link_collision_mesh(r, l);
    if (m.num_faces()) out.push_back({r.link(l).name, m});
  }
  return out;
}

// Only the root box l0 (0.2 x 0.2 x 0.1, centred at the origin, never moves).
std::vector<LinkMesh> root_box_only(const Robot& r) { return {{"l0", link_collision_mesh(r, r.link_index("l0"))}}; }

Eigen::VectorXd random_q(const Robot& r, std::mt19937& rng) {
  Eigen::VectorXd q(r.dof());
  for (int j = 0; j < r.dof(); ++j) {
    double lo = std::isfinite(r.lower_limits()[j]) ? r.lower_limits()[j] : -M_PI;
    double hi = std::isfinite(r.upper_limits()[j]) ? r.upper_limits()[j] : M_PI;
    q[j] = std::uniform_real_distribution<double>(lo, hi)(rng);
  }
  return q;
}

}  // namespace

TEST(Mesh, PrimitivesAreClosedAndOutward) {
  EXPECT_NEAR(volume(TriangleMesh::box({0.1, 0.2, 0.3})), 0.006, 1e-15);
  const int n = 64;
  const double r = 0.05, h = 0.2;
  EXPECT_NEAR(volume(TriangleMesh::cylinder(r, h, n)), 0.5 * n * r * r * std::sin(2 * M_PI / n) * h, 1e-15);
  const double vs = volume(TriangleMesh::sphere(0.1, 48, 96));
  EXPECT_GT(vs, 0.99 * 4.0 / 3.0 * M_PI * 1e-3);
  EXPECT_LT(vs, 4.0 / 3.0 * M_PI * 1e-3);  // inscribed polyhedron
  EXPECT_THROW(TriangleMesh::box({0.1, 0.0, 0.1}), std::invalid_argument);
  EXPECT_THROW(TriangleMesh::cylinder(0.1, 0.1, 2), std::invalid_argument);
}

TEST(Mesh, ObjReaderHandlesQuadsSlashesAndNegativeIndices) {
  const auto path = (std::filesystem::temp_directory_path() / "pickplan_test_quad.obj").string();
  {
    std::ofstream f(path);
    f << "# a unit square as a quad and the same square twice more\nmtllib x.mtl\no sq\n"
         "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nvt 0 0\n"
         "f 1/1/1 2/1/1 3/1/1 4/1/1\nf -4//1 -3//1 -2//1\nusemtl m\nf 1/1 3/1 4/1\n";
  }
  TriangleMesh m = read_obj(path);
  ASSERT_EQ(m.num_vertices(), 4);
  ASSERT_EQ(m.num_faces(), 4);
  EXPECT_EQ(m.faces.row(0), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(m.faces.row(1), Eigen::RowVector3i(0, 2, 3));
  EXPECT_EQ(m.faces.row(2), Eigen::RowVector3i(0, 1, 2));
  EXPECT_EQ(m.faces.row(3), Eigen::RowVector3i(0, 2, 3));
  {
    std::ofstream f(path);
    f << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  }
  try {
    read_obj(path);
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("line 3"), std::string::npos) << e.what();
  }
  std::remove(path.c_str());
  EXPECT_THROW(read_obj(path), FileNotFound);
}

TEST(Mesh, LinkMeshesFollowUrdfOrigins) {
  Robot r = mixed_arm();
  TriangleMesh l1 = link_collision_mesh(r, r.link_index("l1"));  // cylinder r 0.05 l 0.2 at z + 0.1
  EXPECT_NEAR(l1.vertices.col(2).minCoeff(), 0.0, 1e-12);
  EXPECT_NEAR(l1.vertices.col(2).maxCoeff(), 0.2, 1e-12);
  EXPECT_NEAR(l1.vertices.col(0).maxCoeff(), 0.05, 1e-12);
  EXPECT_EQ(link_collision_mesh(r, r.link_index("l2")).num_faces(), 0);
}

TEST(Collision, BoxToBoxDistancesMatchClosedForm) {
  Robot r = mixed_arm();
  // Root box spans x in [-0.1, 0.1]; a 0.1 cube at x = 0.1 + g + 0.05 is g away.
  for (double g : {0.001, 0.013, 0.2}) {
    CollisionChecker c(r, root_box_only(r),
                       {{"cube", TriangleMesh::box({0.1, 0.1, 0.1}), translation(0.15 + g, 0.02, 0.0)}});
    Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
    EXPECT_NEAR(c.min_distance(q), g, 1e-9);
    EXPECT_FALSE(c.in_collision(q));
    EXPECT_TRUE(c.contacts(q).empty());
    auto near = c.contacts(q, 0.5);  // nearest points, in world coordinates
    ASSERT_EQ(near.size(), 1u);
    EXPECT_NEAR(near[0].distance, g, 1e-9);
    EXPECT_NEAR(near[0].point_link.x(), 0.1, 1e-9);
    EXPECT_NEAR(near[0].point_other.x(), 0.1 + g, 1e-9);
  }
  // Overlap of two meshes: in collision, distance 0 (FCL has no mesh-mesh penetration depth).
  CollisionChecker over(r, root_box_only(r),
                        {{"cube", TriangleMesh::box({0.1, 0.1, 0.1}), translation(0.14, 0.02, 0.0)}});
  EXPECT_TRUE(over.in_collision(Eigen::VectorXd::Zero(r.dof())));
  EXPECT_EQ(over.min_distance(Eigen::VectorXd::Zero(r.dof())), 0.0);
  // A cube rotated 45 degrees about z: its edge reaches half-size * sqrt(2) towards the root box.
  const double h = 0.05, g = 0.03;
  CollisionChecker rot(
      r, root_box_only(r),
      {{"cube", TriangleMesh::box({2 * h, 2 * h, 2 * h}), rot_z(M_PI / 4, {0.1 + g + h * std::sqrt(2.0), 0, 0})}});
  EXPECT_NEAR(rot.min_distance(Eigen::VectorXd::Zero(r.dof())), g, 1e-9);
  // Corner to corner: a cube diagonally off the root box's corner (0.1, 0.1, 0.05).
  const Eigen::Vector3d d(0.02, 0.03, 0.04);
  CollisionChecker diag(
      r, root_box_only(r),
      {{"cube", TriangleMesh::box({0.1, 0.1, 0.1}), translation(0.15 + d.x(), 0.15 + d.y(), 0.1 + d.z())}});
  EXPECT_NEAR(diag.min_distance(Eigen::VectorXd::Zero(r.dof())), d.norm(), 1e-9);
}

TEST(Collision, SphereDistanceWithinTessellationBound) {
  Robot r = mixed_arm();
  const double rad = 0.04, gap = 0.025;
  const int rings = 48, sectors = 96;
  // Sphere centre diagonally off the root box corner (0.1, 0.1, 0.05).
  const Eigen::Vector3d dir = Eigen::Vector3d(1, 2, 2).normalized();
  const Eigen::Vector3d centre = Eigen::Vector3d(0.1, 0.1, 0.05) + (rad + gap) * dir;
  CollisionChecker c(
      r, root_box_only(r),
      {{"ball", TriangleMesh::sphere(rad, rings, sectors), translation(centre.x(), centre.y(), centre.z())}});
  const double dist = c.min_distance(Eigen::VectorXd::Zero(r.dof()));
  const double sag = rad * (1 - std::cos(M_PI / rings) * std::cos(M_PI / sectors));  // inscribed mesh vs sphere
  EXPECT_GE(dist, gap - 1e-9);
  EXPECT_LE(dist, gap + sag);
}

TEST(Collision, TableBoxDistanceAndPenetration) {
  Robot r = mixed_arm();
  TableBox table{Eigen::Vector3d(1.0, 1.0, 0.05), translation(0.0, 0.0, -0.05 - 0.025 - 0.02)};  // top 2 cm below l0
  CollisionChecker c(r, root_box_only(r), {}, table);
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  EXPECT_NEAR(c.min_distance(q), 0.02, 1e-7);
  EXPECT_FALSE(c.in_collision(q));
  CollisionSettings s;
  s.margin = 0.03;  // closer than the margin counts
  EXPECT_TRUE(CollisionChecker(r, root_box_only(r), {}, table, s).in_collision(q));
  table.pose = translation(0.0, 0.0, -0.05 - 0.025 + 0.01);  // table top 1 cm into l0
  CollisionChecker hit(r, root_box_only(r), {}, table);
  EXPECT_TRUE(hit.in_collision(q));
  EXPECT_LT(hit.min_distance(q), 0.0);
  auto cs = hit.contacts(q);
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].link, "l0");
  EXPECT_EQ(cs[0].other, "table");
  EXPECT_EQ(cs[0].kind, OtherKind::Table);
  EXPECT_NEAR(cs[0].distance, -0.01, 1e-6);  // FCL's triangle-vs-box depth is exact here
  EXPECT_NEAR(cs[0].point_link.z(), cs[0].point_other.z(), 1e-12);
}

TEST(Collision, ContainmentCountsAsCollision) {
  Robot r = mixed_arm();
  // A 2 cm cube entirely inside the root box: no triangles cross.
  std::vector<SceneObject> inner{{"pebble", TriangleMesh::box({0.02, 0.02, 0.02}), translation(0.03, 0.0, 0.0)}};
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  CollisionChecker c(r, root_box_only(r), inner);
  EXPECT_TRUE(c.in_collision(q));
  EXPECT_NEAR(c.min_distance(q), -0.04, 1e-9);  // minus the surface gap (z: 0.05 - 0.01)
  CollisionSettings s;
  s.detect_containment = false;
  EXPECT_FALSE(CollisionChecker(r, root_box_only(r), inner, {}, s).in_collision(q));
  // The other way round: the root box inside a big hollow object mesh.
  CollisionChecker big(r, root_box_only(r), {{"crate", TriangleMesh::box({1, 1, 1}), translation(0.1, 0, 0)}});
  EXPECT_TRUE(big.in_collision(q));
}

TEST(Collision, AllowedPairsAndExclusions) {
  Robot r = mixed_arm();
  std::vector<SceneObject> objs{{"touching", TriangleMesh::box({0.1, 0.1, 0.1}), translation(0.14, 0, 0)},
                                {"far", TriangleMesh::box({0.1, 0.1, 0.1}), translation(0.5, 0, 0)}};
  const Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  CollisionChecker c(r, root_box_only(r), objs);
  EXPECT_TRUE(c.in_collision(q));
  auto cs = c.contacts(q);
  ASSERT_EQ(cs.size(), 1u);
  EXPECT_EQ(cs[0].other, "touching");
  CollisionSettings allowed;
  allowed.allowed_pairs = {{"touching", "l0"}};  // either order
  CollisionChecker ca(r, root_box_only(r), objs, {}, allowed);
  EXPECT_FALSE(ca.in_collision(q));
  EXPECT_NEAR(ca.min_distance(q), 0.5 - 0.05 - 0.1, 1e-9);
  EXPECT_EQ(ca.num_pairs(), 1);
  CollisionSettings excl;
  excl.excluded_objects = {"touching"};
  EXPECT_FALSE(CollisionChecker(r, root_box_only(r), objs, {}, excl).in_collision(q));
  CollisionSettings bad;
  bad.excluded_objects = {"nope"};
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), objs, {}, bad), std::invalid_argument);
  bad = {};
  bad.allowed_pairs = {{"l0", "nope"}};
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), objs, {}, bad), std::invalid_argument);
  bad = {};
  bad.allowed_pairs = {{"not_a_link", "far"}};
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), objs, {}, bad), std::invalid_argument);
}

// The whole arm against a big box wall: the distance is the gap between the wall's face and
// the arm's farthest vertex along x (computed here from FK and the meshes, not by FCL).
TEST(Collision, ArmAgainstWallMatchesVertexExtent) {
  Robot r = mixed_arm();
  auto meshes = meshes_of(r);
  ASSERT_EQ(meshes.size(), 3u);  // l0 box, l1 cylinder, l4 sphere
  std::mt19937 rng(7);
  RobotWorkspace ws(r);
  int hits = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Eigen::VectorXd q = random_q(r, rng);
    r.forward_kinematics(q.data(), ws);
    double max_x = -1e9;
    for (const auto& lm : meshes) {
      const Transform& T = ws.link_pose[r.link_index(lm.link)];
      for (int i = 0; i < lm.mesh.num_vertices(); ++i)
        max_x = std::max(max_x, T.apply(lm.mesh.vertices.row(i).transpose()).x());
    }
    const double gap = (trial % 2 == 0) ? 0.004 + 0.002 * trial : -0.01;
    const double face = max_x + gap;
    CollisionChecker c(r, meshes, {{"wall", TriangleMesh::box({1, 4, 4}), translation(face + 0.5, 0, 0)}});
    if (gap > 0) {
      EXPECT_NEAR(c.min_distance(q), gap, 1e-9) << "trial " << trial;
      EXPECT_FALSE(c.in_collision(q));
    } else {
      EXPECT_TRUE(c.in_collision(q)) << "trial " << trial;
      EXPECT_LE(c.min_distance(q), 0.0);
      ++hits;
    }
  }
  EXPECT_EQ(hits, 20);
}

TEST(Collision, BatchesEqualSingleCallsAcrossThreads) {
  Robot r = mixed_arm();
  std::vector<SceneObject> objs{{"a", TriangleMesh::box({0.1, 0.1, 0.3}), translation(0.3, 0.1, 0.2)},
                                {"b", TriangleMesh::cylinder(0.05, 0.2), translation(0.0, 0.35, 0.3)}};
  CollisionSettings s;
  s.self_collision = true;
  CollisionChecker c(r, meshes_of(r), objs, {Eigen::Vector3d(2, 2, 0.1), translation(0, 0, -0.2)}, s);
  std::mt19937 rng(3);
  const int B = 300;
  Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> Q(B, r.dof());
  for (int b = 0; b < B; ++b) Q.row(b) = random_q(r, rng).transpose();
  std::vector<char> single(B);
  std::vector<double> dist(B);
  int colliding = 0;
  for (int b = 0; b < B; ++b) {
    Eigen::VectorXd q = Q.row(b).transpose();
    single[b] = c.in_collision(q);
    dist[b] = c.min_distance(q);
    colliding += single[b];
    EXPECT_EQ(bool(single[b]), dist[b] <= 0.0) << b;
  }
  EXPECT_GT(colliding, 10);
  EXPECT_LT(colliding, B - 10);
  for (int threads : {1, 3}) {
    std::unique_ptr<bool[]> out(new bool[B]);
    std::vector<double> d(B);
    c.in_collision_batch(Q.data(), B, out.get(), threads);
    c.min_distance_batch(Q.data(), B, d.data(), threads);
    for (int b = 0; b < B; ++b) {
      EXPECT_EQ(out[b], bool(single[b]));
      EXPECT_EQ(d[b], dist[b]);
    }
  }
}

TEST(Collision, SelfCollisionSkipsAdjacentAndReferencePairs) {
  Robot r = mixed_arm();
  CollisionSettings s;
  s.self_collision = true;
  CollisionChecker c(r, meshes_of(r), {}, {}, s);
  // l1 is l0's child and l4's nearest ancestor with geometry is l1: only (l0, l4) remains.
  auto pairs = c.checked_pairs();
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(std::string("l0"), std::string("l4")));
  // Found by brute force over a grid: some configurations bring the sphere into the base box.
  std::mt19937 rng(11);
  RobotWorkspace ws(r);
  int hit = 0;
  for (int t = 0; t < 2000 && hit < 5; ++t) {
    Eigen::VectorXd q = random_q(r, rng);
    r.forward_kinematics(q.data(), ws);
    const Eigen::Vector3d centre = ws.link_pose[r.link_index("l4")].p;  // sphere centre
    const Eigen::Vector3d out = (centre.cwiseAbs() - Eigen::Vector3d(0.1, 0.1, 0.05)).cwiseMax(0.0);
    const double d_exact = out.norm() - 0.03;  // sphere vs box, valid when the centre is outside
    if (out.norm() > 0 && std::abs(d_exact) > 0.005) {
      EXPECT_EQ(c.in_collision(q), d_exact < 0) << "d_exact " << d_exact;
      if (d_exact < 0) ++hit;
    }
  }
  EXPECT_GT(hit, 0);
}

TEST(Collision, BadInputsThrowClearErrors) {
  Robot r = mixed_arm();
  TriangleMesh empty;
  empty.vertices.resize(0, 3);
  empty.faces.resize(0, 3);
  EXPECT_THROW(CollisionChecker(r, {{"l0", empty}}, {}), std::invalid_argument);
  TriangleMesh bad_index = TriangleMesh::box({0.1, 0.1, 0.1});
  bad_index.faces(3, 1) = 99;
  EXPECT_THROW(CollisionChecker(r, {{"l0", bad_index}}, {}), std::invalid_argument);
  TriangleMesh nan = TriangleMesh::box({0.1, 0.1, 0.1});
  nan.vertices(2, 0) = std::nan("");
  EXPECT_THROW(CollisionChecker(r, {{"l0", nan}}, {}), std::invalid_argument);
  TriangleMesh flat = TriangleMesh::box({0.1, 0.1, 0.1});
  flat.vertices.col(2).setZero();
  flat.vertices.col(1).setZero();
  EXPECT_THROW(CollisionChecker(r, {{"l0", flat}}, {}), std::invalid_argument);
  EXPECT_THROW(CollisionChecker(r, {{"no_such_link", TriangleMesh::box({0.1, 0.1, 0.1})}}, {}), std::invalid_argument);
  auto box = TriangleMesh::box({0.1, 0.1, 0.1});
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), {{"x", box, {}}, {"x", box, {}}}), std::invalid_argument);
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), {{"table", box, {}}}), std::invalid_argument);
  Transform skew;
  skew.R(0, 1) = 0.3;
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), {{"x", box, skew}}), std::invalid_argument);
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), {}, {Eigen::Vector3d(1, -1, 1), {}}), std::invalid_argument);
  CollisionSettings s;
  s.margin = -0.01;
  EXPECT_THROW(CollisionChecker(r, root_box_only(r), {}, {}, s), std::invalid_argument);
  CollisionChecker c(r, root_box_only(r), {{"x", box, translation(1, 0, 0)}});
  Eigen::VectorXd q = Eigen::VectorXd::Zero(r.dof());
  q[1] = std::nan("");
  EXPECT_THROW(c.in_collision(q), std::invalid_argument);
  EXPECT_THROW(c.min_distance(Eigen::VectorXd::Zero(r.dof() + 1)), std::invalid_argument);
  try {
    c.in_collision(Eigen::VectorXd::Zero(2));
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("expected " + std::to_string(r.dof())), std::string::npos) << e.what();
  }
}

// A shape (mesh + BVH) built once and placed by several checkers answers as each checker's own
// copy of the mesh does.
TEST(Collision, SharedShapesAnswerAsOwnMeshes) {
  Robot r = mixed_arm();
  auto cube = std::make_shared<const CollisionShape>(TriangleMesh::box({0.1, 0.1, 0.1}), "cube");
  std::vector<LinkMesh> shared_links;
  for (const LinkMesh& lm : meshes_of(r))
    shared_links.push_back({lm.link, TriangleMesh{}, std::make_shared<const CollisionShape>(lm.mesh, lm.link)});
  int colliding = 0, free = 0;
  for (const Transform& pose : {translation(0.35, 0.02, 0.0), rot_z(0.7, {0.3, -0.2, 0.1})}) {
    CollisionChecker own(r, meshes_of(r), {{"cube", TriangleMesh::box({0.1, 0.1, 0.1}), pose}});
    CollisionChecker shared(r, shared_links, {{"cube", TriangleMesh{}, pose, cube}});
    std::mt19937 rng(3);
    for (int k = 0; k < 200; ++k) {
      const Eigen::VectorXd q = random_q(r, rng);
      EXPECT_EQ(own.min_distance(q), shared.min_distance(q));
      const bool hit = own.in_collision(q);
      EXPECT_EQ(hit, shared.in_collision(q));
      (hit ? colliding : free) += 1;
    }
  }
  EXPECT_GT(colliding, 0);
  EXPECT_GT(free, 0);
  EXPECT_THROW(CollisionShape(TriangleMesh{}, "empty"), std::invalid_argument);
}
