#include "pickplan/geometry/collision.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>

#include <fcl/fcl.h>
#include <Eigen/Geometry>

#include "collision_detail.hpp"
#include "pickplan/core/errors.hpp"
#include "pickplan/geometry/sdf.hpp"

namespace pickplan::geometry {
namespace {

using detail::bounds;
constexpr double kInf = std::numeric_limits<double>::infinity();
const char* const kTable = "table";

fcl::Transform3d to_fcl(const core::Transform& T) {
  fcl::Transform3d tf = fcl::Transform3d::Identity();
  tf.linear() = T.R;
  tf.translation() = T.p;
  return tf;
}

std::shared_ptr<const CollisionShape> shape_of(std::shared_ptr<const CollisionShape> shape, TriangleMesh& mesh,
                                               const std::string& what) {
  return shape ? shape : std::make_shared<const CollisionShape>(std::move(mesh), what);
}

}  // namespace

struct CollisionChecker::Impl {
  // Geometry in its own frame comes from a shared CollisionShape; only placement is per checker.
  struct LinkGeom {
    int link;
    std::shared_ptr<const CollisionShape> shape;
    const fcl::CollisionGeometryd* bvh;  // shape's
    Eigen::AlignedBox3d box;             // link frame
    Eigen::Vector3d center;              // bounding sphere, link frame
    double radius;
    const TriangleMesh& mesh() const { return shape->mesh(); }
  };
  struct ObjGeom {
    std::string name;
    std::shared_ptr<const CollisionShape> shape;
    const fcl::CollisionGeometryd* bvh;  // a BVH, or a solid primitive (shape->solid())
    core::Transform pose, inv_pose;
    fcl::Transform3d tf;
    Eigen::AlignedBox3d box, world_box;
    Eigen::Vector3d probe_world;  // a vertex, for the object-inside-link test
    const TriangleMesh& mesh() const { return shape->mesh(); }
  };
  std::vector<LinkGeom> links;
  std::vector<ObjGeom> objects;
  bool has_table = false;
  std::shared_ptr<fcl::Boxd> table;
  fcl::Transform3d table_tf;
  Eigen::AlignedBox3d table_world_box;
  core::Transform table_inv;
  Eigen::Vector3d table_half = Eigen::Vector3d::Zero();

  const fcl::CollisionGeometryd* other_geom(OtherKind k, int i) const {
    if (k == OtherKind::Object) return objects[i].bvh;
    if (k == OtherKind::Table) return table.get();
    return links[i].bvh;
  }
};

CollisionWorkspace::CollisionWorkspace(const CollisionChecker& checker) : robot(checker.robot()) {
  order.reserve(checker.num_pairs());
}

CollisionChecker::~CollisionChecker() = default;
CollisionChecker::CollisionChecker(CollisionChecker&&) noexcept = default;
CollisionChecker& CollisionChecker::operator=(CollisionChecker&&) noexcept = default;

namespace {

// The robot's link meshes, each link at most once; returns each link's geometry index (-1: none).
std::vector<int> add_link_geometry(const core::Robot& robot, std::vector<LinkMesh> link_meshes,
                                   CollisionChecker::Impl& impl) {
  std::vector<int> geom_of_link(robot.num_links(), -1);
  for (auto& lm : link_meshes) {
    const int li = robot.link_index(lm.link);
    if (geom_of_link[li] >= 0) throw std::invalid_argument("link mesh for '" + lm.link + "' given twice");
    auto shape = shape_of(std::move(lm.shape), lm.mesh, "mesh of link '" + lm.link + "'");
    if (shape->primitive()) throw std::invalid_argument("link '" + lm.link + "': a link's geometry must be a mesh");
    const fcl::CollisionGeometryd* bvh = shape->bvh().model.get();
    CollisionChecker::Impl::LinkGeom g{li, shape, bvh, shape->box(), shape->center(), shape->radius()};
    geom_of_link[li] = static_cast<int>(impl.links.size());
    impl.links.push_back(std::move(g));
  }
  return geom_of_link;
}

// The scene's objects at their (rigid) poses, names unique and not reserved; returns their names.
std::vector<std::string> add_object_geometry(std::vector<SceneObject> objects, CollisionChecker::Impl& impl) {
  std::set<std::string> names;
  for (auto& o : objects) {
    if (o.name.empty() || o.name == kTable)
      throw std::invalid_argument("object name '" + o.name + "' is reserved or empty");
    if (!names.insert(o.name).second) throw std::invalid_argument("object name '" + o.name + "' given twice");
    core::require_rigid(("pose of object '" + o.name + "'").c_str(), o.pose.matrix());
    CollisionChecker::Impl::ObjGeom g;
    g.name = o.name;
    g.shape = shape_of(std::move(o.shape), o.mesh, "mesh of object '" + o.name + "'");
    g.bvh = g.shape->bvh().model.get();
    g.pose = o.pose;
    g.inv_pose = o.pose.inverse();
    g.tf = to_fcl(o.pose);
    g.box = g.shape->box();
    g.world_box = bounds(g.mesh(), o.pose);
    g.probe_world = o.pose.apply(g.mesh().vertices.row(0).transpose());
    impl.objects.push_back(std::move(g));
  }
  return {names.begin(), names.end()};
}

// The table box (all-zero size: no table).
void add_table_geometry(const TableBox& table, CollisionChecker::Impl& impl) {
  core::require_finite("table size", table.size.data(), 3);
  if (table.size.isZero()) return;
  if (!(table.size.array() > 0).all())
    throw std::invalid_argument("table size: expected 3 positive extents (or all zero for no table)");
  core::require_rigid("table pose", table.pose.matrix());
  impl.has_table = true;
  impl.table = std::make_shared<fcl::Boxd>(table.size);
  impl.table_tf = to_fcl(table.pose);
  impl.table_inv = table.pose.inverse();
  impl.table_half = 0.5 * table.size;
  for (int c = 0; c < 8; ++c)
    impl.table_world_box.extend(
        table.pose.apply(0.5 * Eigen::Vector3d((c & 1 ? 1 : -1) * table.size.x(), (c & 2 ? 1 : -1) * table.size.y(),
                                               (c & 4 ? 1 : -1) * table.size.z())));
}

}  // namespace

CollisionChecker::CollisionChecker(const core::Robot& robot, std::vector<LinkMesh> link_meshes,
                                   std::vector<SceneObject> objects, const TableBox& table, CollisionSettings settings)
    : robot_(robot), settings_(std::move(settings)), impl_(std::make_unique<Impl>()) {
  if (!(settings_.margin >= 0.0) || !std::isfinite(settings_.margin))
    throw std::invalid_argument("margin: expected a finite value >= 0, got " + std::to_string(settings_.margin));
  const std::vector<int> geom_of_link = add_link_geometry(robot_, std::move(link_meshes), *impl_);
  const std::vector<std::string> names = add_object_geometry(std::move(objects), *impl_);
  add_table_geometry(table, *impl_);
  choose_pairs(names, geom_of_link);
}

void CollisionChecker::choose_pairs(const std::vector<std::string>& object_names,
                                    const std::vector<int>& geom_of_link) {
  const std::set<std::string> names(object_names.begin(), object_names.end());
  // Exclusions and allowed pairs, by name.
  std::set<std::string> excluded;
  for (const auto& n : settings_.excluded_objects) {
    if (!names.count(n) && !(n == kTable && impl_->has_table))
      throw std::invalid_argument("excluded_objects: unknown object '" + n + "'");
    excluded.insert(n);
  }
  auto is_link = [&](const std::string& n) {
    const auto& ln = robot_.link_names();
    return std::find(ln.begin(), ln.end(), n) != ln.end();
  };
  std::set<std::pair<std::string, std::string>> allowed;
  for (auto [a, b] : settings_.allowed_pairs) {
    if (!is_link(a) && is_link(b)) std::swap(a, b);
    robot_.link_index(a);  // throws, naming the links
    if (!names.count(b) && !(b == kTable && impl_->has_table) && !is_link(b))
      throw std::invalid_argument("allowed_pairs: unknown object or link '" + b + "' (paired with link '" + a + "')");
    allowed.insert({a, b});
    if (is_link(b)) allowed.insert({b, a});
  }
  auto link_name = [&](int g) { return robot_.link(impl_->links[g].link).name; };
  const int nl = static_cast<int>(impl_->links.size());
  for (int g = 0; g < nl; ++g) {
    if (impl_->has_table && !excluded.count(kTable) && !allowed.count({link_name(g), kTable}))
      pairs_.push_back({g, OtherKind::Table, -1});
    for (int o = 0; o < static_cast<int>(impl_->objects.size()); ++o) {
      const auto& on = impl_->objects[o].name;
      if (!excluded.count(on) && !allowed.count({link_name(g), on})) pairs_.push_back({g, OtherKind::Object, o});
    }
  }
  if (!settings_.self_collision) return;
  // Link pairs: not a link and its geometric parent, not allowed, and apart at the reference configuration.
  std::vector<double> ref = settings_.self_collision_reference;
  if (ref.empty()) {
    ref.assign(robot_.dof(), 0.0);
    for (int j = 0; j < robot_.dof(); ++j) ref[j] = std::clamp(0.0, robot_.lower_limits()[j], robot_.upper_limits()[j]);
  }
  robot_.check_configuration(ref.data(), static_cast<long>(ref.size()));
  CollisionWorkspace ws(*this);
  robot_.forward_kinematics(ref.data(), ws.robot);
  auto geometric_parent = [&](int g) {
    for (int l = robot_.link(impl_->links[g].link).parent; l >= 0; l = robot_.link(l).parent)
      if (geom_of_link[l] >= 0) return geom_of_link[l];
    return -1;
  };
  for (int a = 0; a < nl; ++a)
    for (int b = a + 1; b < nl; ++b) {
      if (geometric_parent(a) == b || geometric_parent(b) == a) continue;
      if (allowed.count({link_name(a), link_name(b)})) continue;
      Pair p{a, OtherKind::Link, b};
      if (pair_collides(p, ws)) continue;
      pairs_.push_back(p);
    }
}

std::vector<std::pair<std::string, std::string>> CollisionChecker::checked_pairs() const {
  std::vector<std::pair<std::string, std::string>> out;
  for (const auto& p : pairs_) {
    const std::string a = robot_.link(impl_->links[p.link_geom].link).name;
    if (p.kind == OtherKind::Table)
      out.emplace_back(a, kTable);
    else if (p.kind == OtherKind::Object)
      out.emplace_back(a, impl_->objects[p.other].name);
    else
      out.emplace_back(a, robot_.link(impl_->links[p.other].link).name);
  }
  return out;
}

void CollisionChecker::set_object_pose(const std::string& name, const core::Transform& pose) {
  core::require_rigid(("pose of object '" + name + "'").c_str(), pose.matrix());
  for (auto& g : impl_->objects) {
    if (g.name != name) continue;
    g.pose = pose;
    g.inv_pose = pose.inverse();
    g.tf = to_fcl(pose);
    g.world_box = bounds(g.mesh(), pose);
    g.probe_world = pose.apply(g.mesh().vertices.row(0).transpose());
    return;
  }
  throw std::invalid_argument("set_object_pose: unknown object '" + name + "'");
}

std::vector<std::string> CollisionChecker::object_names() const {
  std::vector<std::string> out;
  for (const auto& o : impl_->objects) out.push_back(o.name);
  return out;
}

std::vector<double> CollisionChecker::link_reach() const {
  std::vector<double> out(robot_.num_links(), 0.0);
  for (const auto& g : impl_->links) out[g.link] = std::max(out[g.link], g.center.norm() + g.radius);
  return out;
}

void CollisionChecker::check_q(const double* q) const { robot_.check_configuration(q, robot_.dof()); }

double CollisionChecker::pair_lower_bound(const Pair& p, const CollisionWorkspace& ws) const {
  const auto& lg = impl_->links[p.link_geom];
  const Eigen::Vector3d c = ws.robot.link_pose[lg.link].apply(lg.center);
  double d;
  if (p.kind == OtherKind::Link) {
    const auto& og = impl_->links[p.other];
    d = (c - ws.robot.link_pose[og.link].apply(og.center)).norm() - og.radius;
  } else if (p.kind == OtherKind::Table) {
    d = box_signed_distance(impl_->table_inv.apply(c), impl_->table_half, nullptr);  // exact, not its world box
  } else {
    const auto& og = impl_->objects[p.other];
    const Primitive* prim = og.shape->primitive();
    d = prim ? prim->signed_distance(og.inv_pose.apply(c)) : og.world_box.exteriorDistance(c);
  }
  d -= lg.radius;
  return d > 0.0 ? d : -kInf;  // only separated bounding volumes give a usable bound
}

namespace {

// True when some vertex of `inner` (placed by T_inner) lies inside the closed mesh `outer`
// (placed by T_outer). With no triangle crossing, one vertex decides for the whole mesh.
bool contained(const TriangleMesh& inner_mesh, const core::Transform& T_inner, const TriangleMesh& outer,
               const Eigen::AlignedBox3d& outer_box, const core::Transform& T_outer_inv) {
  const Eigen::Vector3d p = T_outer_inv.apply(T_inner.apply(inner_mesh.vertices.row(0).transpose()));
  return outer_box.contains(p) && outer.winding_number(p) > 0.5;
}

}  // namespace

bool CollisionChecker::pair_collides(const Pair& p, const CollisionWorkspace& ws) const {
  const auto& lg = impl_->links[p.link_geom];
  const core::Transform& Tl = ws.robot.link_pose[lg.link];
  const fcl::Transform3d tf_link = to_fcl(Tl);
  fcl::CollisionRequestd req(1, false);
  fcl::CollisionResultd res;
  if (p.kind == OtherKind::Table) {
    fcl::collide(lg.bvh, tf_link, impl_->table.get(), impl_->table_tf, req, res);
    return res.isCollision();
  }
  if (p.kind == OtherKind::Object) {
    const auto& og = impl_->objects[p.other];
    fcl::collide(lg.bvh, tf_link, og.bvh, og.tf, req, res);
    if (res.isCollision()) return true;
    if (!settings_.detect_containment) return false;
    // Whatever lies inside a solid already collides with it (FCL meets its triangles or its solid).
    return (!og.shape->solid() && contained(lg.mesh(), Tl, og.mesh(), og.box, og.inv_pose)) ||
           (!lg.shape->solid() && contained(og.mesh(), og.pose, lg.mesh(), lg.box, Tl.inverse()));
  }
  const auto& og = impl_->links[p.other];
  const core::Transform& To = ws.robot.link_pose[og.link];
  fcl::collide(lg.bvh, tf_link, og.bvh, to_fcl(To), req, res);
  if (res.isCollision()) return true;
  if (!settings_.detect_containment) return false;
  return (!og.shape->solid() && contained(lg.mesh(), Tl, og.mesh(), og.box, To.inverse())) ||
         (!lg.shape->solid() && contained(og.mesh(), To, lg.mesh(), lg.box, Tl.inverse()));
}

double CollisionChecker::pair_distance(const Pair& p, const CollisionWorkspace& ws, bool want_points,
                                       ContactInfo* info) const {
  const auto& lg = impl_->links[p.link_geom];
  const core::Transform& Tl = ws.robot.link_pose[lg.link];
  const fcl::Transform3d tf_link = to_fcl(Tl);
  const fcl::CollisionGeometryd* other = impl_->other_geom(p.kind, p.other);
  const fcl::Transform3d tf_other = p.kind == OtherKind::Object ? impl_->objects[p.other].tf
                                    : p.kind == OtherKind::Table
                                        ? impl_->table_tf
                                        : to_fcl(ws.robot.link_pose[impl_->links[p.other].link]);
  fcl::DistanceRequestd dreq(want_points);
  fcl::DistanceResultd dres;
  fcl::distance(lg.bvh, tf_link, other, tf_other, dreq, dres);
  double d = dres.min_distance;
  Eigen::Vector3d pl = dres.nearest_points[0], po = dres.nearest_points[1];
  if (d <= 1e-12) {
    // Touching or intersecting. FCL's contacts carry a usable depth only against the solid
    // table box (per triangle, by MPR); for two triangle surfaces the per-triangle-pair
    // "depths" say nothing about the bodies, so the value stays 0 (touching or intersecting).
    // Solids (the table, primitives) give FCL's per-triangle depths a meaning.
    const bool table = p.kind == OtherKind::Table || lg.shape->solid() ||
                       (p.kind == OtherKind::Object && impl_->objects[p.other].shape->solid()) ||
                       (p.kind == OtherKind::Link && impl_->links[p.other].shape->solid());
    fcl::CollisionRequestd creq(table ? 64 : 1, true);
    fcl::CollisionResultd cres;
    fcl::collide(lg.bvh, tf_link, other, tf_other, creq, cres);
    const Primitive* prim = p.kind == OtherKind::Object ? impl_->objects[p.other].shape->primitive() : nullptr;
    if (cres.isCollision() && prim && !lg.shape->solid()) {
      // FCL's per-triangle depths are no body's (a triangle lying inside a thin board gets one to the
      // board's far corner): the deepest link vertex or contact point inside the solid, in closed form.
      std::vector<Eigen::Vector3d> x;
      for (int i = 0; i < lg.mesh().num_vertices(); ++i) x.push_back(Tl.apply(lg.mesh().vertices.row(i).transpose()));
      for (size_t i = 0; i < cres.numContacts(); ++i) x.push_back(cres.getContact(i).pos);
      const auto [depth, k] = prim->deepest(x, impl_->objects[p.other].inv_pose);
      d = -depth;
      if (k >= 0) pl = po = x[k];
    } else if (cres.isCollision()) {
      double depth = 0.0;
      for (size_t i = 0; i < cres.numContacts(); ++i) {
        const auto& c = cres.getContact(i);
        if (i == 0 || c.penetration_depth > depth) {
          depth = std::max(0.0, c.penetration_depth);
          pl = po = c.pos;
        }
      }
      d = table ? -depth : 0.0;
    } else {
      d = std::max(d, 0.0);
    }
  } else if (settings_.detect_containment && p.kind != OtherKind::Table) {
    const bool self = p.kind == OtherKind::Link;
    const TriangleMesh& om = self ? impl_->links[p.other].mesh() : impl_->objects[p.other].mesh();
    const Eigen::AlignedBox3d& ob = self ? impl_->links[p.other].box : impl_->objects[p.other].box;
    const core::Transform To = self ? ws.robot.link_pose[impl_->links[p.other].link] : impl_->objects[p.other].pose;
    // Apart from a solid, nothing is inside it.
    const bool solid = self ? impl_->links[p.other].shape->solid() : impl_->objects[p.other].shape->solid();
    if ((!solid && contained(lg.mesh(), Tl, om, ob, To.inverse())) ||
        (!lg.shape->solid() && contained(om, To, lg.mesh(), lg.box, Tl.inverse())))
      d = -d;
  }
  if (info) {
    info->link = robot_.link(lg.link).name;
    info->kind = p.kind;
    info->other = p.kind == OtherKind::Object  ? impl_->objects[p.other].name
                  : p.kind == OtherKind::Table ? std::string(kTable)
                                               : robot_.link(impl_->links[p.other].link).name;
    info->distance = d;
    // FCL reports BVH nearest points in world coordinates (0.7 convention).
    info->point_link = pl;
    info->point_other = po;
  }
  return d;
}

bool CollisionChecker::in_collision(const double* q, CollisionWorkspace& ws) const {
  check_q(q);
  robot_.forward_kinematics(q, ws.robot);
  return in_collision_posed(ws);
}

bool CollisionChecker::in_collision_posed(CollisionWorkspace& ws) const {
  const double m = settings_.margin;
  for (const auto& p : pairs_) {
    if (pair_lower_bound(p, ws) > m) continue;
    if (pair_collides(p, ws)) return true;
    if (m > 0.0 && pair_distance(p, ws, false, nullptr) < m) return true;
  }
  return false;
}

double CollisionChecker::min_distance(const double* q, CollisionWorkspace& ws, double cap) const {
  check_q(q);
  robot_.forward_kinematics(q, ws.robot);
  ws.order.clear();
  for (int i = 0; i < num_pairs(); ++i) {
    const double lb = pair_lower_bound(pairs_[i], ws);
    if (lb < cap) ws.order.emplace_back(lb, i);
  }
  std::sort(ws.order.begin(), ws.order.end());
  double best = cap;
  for (const auto& [lb, i] : ws.order) {
    if (lb >= best) break;  // sorted: no later pair can be closer
    best = std::min(best, pair_distance(pairs_[i], ws, false, nullptr));
  }
  return best;
}

bool CollisionChecker::in_collision(const Eigen::VectorXd& q) const {
  core::require_size("configuration", robot_.dof(), q.size(), "joint values");
  CollisionWorkspace ws(*this);
  return in_collision(q.data(), ws);
}

double CollisionChecker::min_distance(const Eigen::VectorXd& q) const {
  core::require_size("configuration", robot_.dof(), q.size(), "joint values");
  CollisionWorkspace ws(*this);
  return min_distance(q.data(), ws);
}

std::vector<ContactInfo> CollisionChecker::contacts(const Eigen::VectorXd& q, double within) const {
  core::require_size("configuration", robot_.dof(), q.size(), "joint values");
  check_q(q.data());
  if (!(within >= 0.0)) throw std::invalid_argument("within: expected a value >= 0");
  CollisionWorkspace ws(*this);
  robot_.forward_kinematics(q.data(), ws.robot);
  const double thr = std::max(settings_.margin, within);
  std::vector<ContactInfo> out;
  for (const auto& p : pairs_) {
    if (pair_lower_bound(p, ws) > thr) continue;
    ContactInfo info;
    const double d = pair_distance(p, ws, true, &info);
    if (d < thr || d <= 0.0) out.push_back(std::move(info));
  }
  std::sort(out.begin(), out.end(), [](const ContactInfo& a, const ContactInfo& b) { return a.distance < b.distance; });
  return out;
}

}  // namespace pickplan::geometry
