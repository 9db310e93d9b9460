// CollisionShape: a mesh (an FCL BVH), a convex hull or a primitive, with its bounds.
#include <algorithm>

#include "collision_detail.hpp"
#include "pickplan/geometry/collision.hpp"

namespace pickplan::geometry {
namespace {

using FclBvh = fcl::BVHModel<fcl::OBBRSSd>;

std::shared_ptr<FclBvh> make_bvh(const TriangleMesh& m) {
  std::vector<fcl::Vector3d> v(m.num_vertices());
  std::vector<fcl::Triangle> t(m.num_faces());
  for (int i = 0; i < m.num_vertices(); ++i) v[i] = m.vertices.row(i).transpose();
  for (int i = 0; i < m.num_faces(); ++i) t[i] = fcl::Triangle(m.faces(i, 0), m.faces(i, 1), m.faces(i, 2));
  auto bvh = std::make_shared<FclBvh>();
  bvh->beginModel(static_cast<int>(t.size()), static_cast<int>(v.size()));
  bvh->addSubModel(v, t);
  bvh->endModel();
  bvh->computeLocalAABB();
  return bvh;
}

}  // namespace

using detail::bounds;

CollisionShape::CollisionShape(TriangleMesh mesh, const std::string& what) : mesh_(std::move(mesh)) {
  mesh_.validate(what);
  bvh_ = std::make_unique<Bvh>(Bvh{make_bvh(mesh_)});
  box_ = bounds(mesh_);
  center_ = box_.center();
  for (int i = 0; i < mesh_.num_vertices(); ++i)
    radius_ = std::max(radius_, (mesh_.vertices.row(i).transpose() - center_).norm());
}

std::shared_ptr<CollisionShape> CollisionShape::convex(TriangleMesh hull, const std::string& what) {
  hull.validate(what);
  std::shared_ptr<CollisionShape> s(new CollisionShape());
  s->mesh_ = std::move(hull);
  s->solid_ = true;
  auto vertices = std::make_shared<std::vector<fcl::Vector3d>>();
  for (int i = 0; i < s->mesh_.num_vertices(); ++i) vertices->push_back(s->mesh_.vertices.row(i).transpose());
  auto faces = std::make_shared<std::vector<int>>();
  for (int f = 0; f < s->mesh_.num_faces(); ++f)
    faces->insert(faces->end(), {3, s->mesh_.faces(f, 0), s->mesh_.faces(f, 1), s->mesh_.faces(f, 2)});
  auto geometry = std::make_shared<fcl::Convexd>(vertices, s->mesh_.num_faces(), faces);
  geometry->computeLocalAABB();
  s->bvh_ = std::make_unique<Bvh>(Bvh{geometry});
  s->box_ = bounds(s->mesh_);
  s->center_ = s->box_.center();
  for (int i = 0; i < s->mesh_.num_vertices(); ++i)
    s->radius_ = std::max(s->radius_, (s->mesh_.vertices.row(i).transpose() - s->center_).norm());
  return s;
}

CollisionShape::CollisionShape(const Primitive& primitive, const std::string& what)
    : solid_(true), has_primitive_(true), primitive_(primitive) {
  primitive.validate(what);
  mesh_ = primitive.enclosing_mesh();
  std::shared_ptr<fcl::CollisionGeometryd> geometry;
  switch (primitive.kind) {
    case PrimitiveKind::Box:
      geometry = std::make_shared<fcl::Boxd>(primitive.size);
      break;
    case PrimitiveKind::Cylinder:
      geometry = std::make_shared<fcl::Cylinderd>(primitive.size.x(), primitive.size.y());
      break;
    case PrimitiveKind::Sphere:
      geometry = std::make_shared<fcl::Sphered>(primitive.size.x());
      break;
  }
  geometry->computeLocalAABB();
  bvh_ = std::make_unique<Bvh>(Bvh{geometry});
  box_ = primitive.bounds();
  center_ = Eigen::Vector3d::Zero();
  radius_ = box_.max().norm();
}

CollisionShape::~CollisionShape() = default;

}  // namespace pickplan::geometry
