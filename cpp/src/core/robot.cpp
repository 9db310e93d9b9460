#include "pickplan/core/robot.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <urdf_parser/urdf_parser.h>
#include <Eigen/SVD>

#include "pickplan/core/errors.hpp"

namespace fs = std::filesystem;

namespace pickplan::core {
namespace {

constexpr int kMaxUrdfNesting = 64;  // real URDFs nest 5-6 deep (robot, link, collision, geometry, mesh)

Transform to_transform(const urdf::Pose& pose) {
  Transform T;
  double x, y, z, w;
  pose.rotation.getQuaternion(x, y, z, w);
  T.R = Eigen::Quaterniond(w, x, y, z).normalized().toRotationMatrix();
  T.p = Eigen::Vector3d(pose.position.x, pose.position.y, pose.position.z);
  return T;
}

std::string read_file(const std::string& path) {
  if (!fs::is_regular_file(path)) throw FileNotFound("URDF file not found: '" + path + "'");
  std::ifstream in(path);
  std::stringstream buf;
  buf << in.rdbuf();
  return buf.str();
}

// Resolves a URDF mesh reference to an absolute path, or "" when nothing exists.
std::string resolve_mesh(const std::string& uri, const fs::path& base_dir,
                         const std::vector<std::string>& package_dirs) {
  const std::string pkg = "package://", file = "file://";
  std::vector<fs::path> candidates;
  if (uri.rfind(pkg, 0) == 0) {
    std::string rest = uri.substr(pkg.size());
    auto slash = rest.find('/');
    std::string package = rest.substr(0, slash);
    std::string inner = slash == std::string::npos ? "" : rest.substr(slash + 1);
    for (const auto& dir : package_dirs) {
      candidates.push_back(fs::path(dir) / package / inner);
      if (fs::path(dir).filename() == package) candidates.push_back(fs::path(dir) / inner);
    }
    // Many URDFs (pybullet_data's included) name a folder next to the URDF as the package.
    for (fs::path dir = base_dir; !dir.empty(); dir = dir.parent_path()) {
      candidates.push_back(dir / package / inner);
      if (dir.filename() == package) candidates.push_back(dir / inner);
      if (dir == dir.parent_path()) break;
    }
  } else if (uri.rfind(file, 0) == 0) {
    candidates.push_back(fs::path(uri.substr(file.size())));
  } else {
    fs::path p(uri);
    candidates.push_back(p.is_absolute() ? p : base_dir / p);
  }
  for (const auto& c : candidates)
    if (fs::is_regular_file(c)) return fs::absolute(c).lexically_normal().string();
  return "";
}

// Order of first appearance of each <joint name="..."> in the document, so that the
// configuration follows the URDF's own joint order (as PyBullet does). A linear scan: std::regex
// recurses per character and overflows the stack on long tags.
std::map<std::string, int> joint_document_order(const std::string& xml) {
  std::map<std::string, int> order;
  int k = 0;
  for (size_t at = xml.find('<'); at != std::string::npos; at = xml.find('<', at + 1)) {
    size_t i = at + 1;
    while (i < xml.size() && std::isspace(static_cast<unsigned char>(xml[i]))) ++i;
    if (xml.compare(i, 5, "joint") != 0) continue;
    i += 5;
    if (i >= xml.size() || !std::isspace(static_cast<unsigned char>(xml[i]))) continue;
    const size_t end = xml.find('>', i);
    if (end == std::string::npos) break;
    for (size_t n = xml.find("name", i); n != std::string::npos && n < end; n = xml.find("name", n + 4)) {
      if (!std::isspace(static_cast<unsigned char>(xml[n - 1]))) continue;
      size_t j = n + 4;
      while (j < end && std::isspace(static_cast<unsigned char>(xml[j]))) ++j;
      if (j >= end || xml[j] != '=') continue;
      ++j;
      while (j < end && std::isspace(static_cast<unsigned char>(xml[j]))) ++j;
      if (j >= end || (xml[j] != '"' && xml[j] != '\'')) continue;
      const size_t close = xml.find(xml[j], j + 1);
      if (close == std::string::npos || close > end) break;
      order.emplace(xml.substr(j + 1, close - j - 1), k++);
      break;
    }
  }
  return order;
}

// The deepest element nesting of an XML document, counted without recursion: the XML parser
// recurses once per level and a document nested 100,000 deep overflows the stack.
int xml_nesting_depth(const std::string& xml) {
  int depth = 0, deepest = 0;
  size_t i = 0;
  while ((i = xml.find('<', i)) != std::string::npos) {
    if (xml.compare(i, 4, "<!--") == 0) {
      i = xml.find("-->", i + 4);
    } else if (xml.compare(i, 9, "<![CDATA[") == 0) {
      i = xml.find("]]>", i + 9);
    } else if (i + 1 < xml.size() && (xml[i + 1] == '?' || xml[i + 1] == '!')) {
      i = xml.find('>', i + 1);
    } else if (i + 1 < xml.size() && xml[i + 1] == '/') {
      --depth;
      i = xml.find('>', i + 1);
    } else {
      char quote = 0;  // a '>' inside a quoted attribute value does not end the tag
      size_t j = i + 1;
      for (; j < xml.size(); ++j) {
        if (quote) {
          if (xml[j] == quote) quote = 0;
        } else if (xml[j] == '"' || xml[j] == '\'') {
          quote = xml[j];
        } else if (xml[j] == '>') {
          break;
        }
      }
      if (j >= xml.size()) break;
      if (xml[j - 1] != '/') deepest = std::max(deepest, ++depth);
      i = j;
    }
    if (i == std::string::npos) break;
    ++i;
  }
  return deepest;
}

void require_positive(const std::string& source, const std::string& link, const char* what, double value) {
  if (!(std::isfinite(value) && value > 0.0))
    throw std::invalid_argument("URDF '" + source + "': link '" + link + "': collision " + what +
                                " must be a finite number > 0, got " + std::to_string(value));
}

void require_finite_pose(const std::string& source, const std::string& what, const urdf::Pose& pose) {
  double x, y, z, w;
  pose.rotation.getQuaternion(x, y, z, w);
  const double v[7] = {pose.position.x, pose.position.y, pose.position.z, x, y, z, w};
  for (double e : v)
    if (!std::isfinite(e))
      throw std::invalid_argument("URDF '" + source + "': " + what + ": origin has NaN or infinity");
}

// The urdfdom model of a URDF document, its nesting checked first (the parser recurses per level).
urdf::ModelInterfaceSharedPtr parse_urdf_model(const std::string& xml, const std::string& source) {
  const int depth = xml_nesting_depth(xml);
  if (depth > kMaxUrdfNesting)
    throw std::invalid_argument("malformed URDF '" + source + "': elements nested " + std::to_string(depth) +
                                " deep (at most " + std::to_string(kMaxUrdfNesting) + ")");
  urdf::ModelInterfaceSharedPtr model;
  try {
    model = urdf::parseURDF(xml);
  } catch (const std::exception& e) {
    throw std::invalid_argument("malformed URDF '" + source + "': " + e.what());
  }
  if (!model || !model->getRoot())
    throw std::invalid_argument("malformed URDF '" + source +
                                "': urdfdom could not parse it (not a <robot> document, or a broken link/joint tree)");
  return model;
}

// The joint into a link: its type, origin and unit axis (moving joints), and its mimic (source
// resolved by the caller once every joint is numbered).
void read_joint(const urdf::Joint& j, const std::string& source, Link& link) {
  link.joint_name = j.name;
  require_finite_pose(source, "joint '" + j.name + "'", j.parent_to_joint_origin_transform);
  link.joint_origin = to_transform(j.parent_to_joint_origin_transform);
  switch (j.type) {
    case urdf::Joint::FIXED:
      link.joint_type = JointType::Fixed;
      break;
    case urdf::Joint::REVOLUTE:
      link.joint_type = JointType::Revolute;
      break;
    case urdf::Joint::CONTINUOUS:
      link.joint_type = JointType::Continuous;
      break;
    case urdf::Joint::PRISMATIC:
      link.joint_type = JointType::Prismatic;
      break;
    default:
      throw std::invalid_argument("URDF '" + source + "': joint '" + j.name +
                                  "' has an unsupported type (floating/planar); model planar bases as "
                                  "two prismatic joints and a revolute joint");
  }
  if (link.joint_type == JointType::Fixed) return;
  const Eigen::Vector3d axis(j.axis.x, j.axis.y, j.axis.z);
  if (!axis.allFinite() || axis.norm() < 1e-12)
    throw std::invalid_argument("URDF '" + source + "': joint '" + j.name + "' has a zero or non-finite axis");
  link.axis = axis.normalized();
  link.axis_is_z = (link.axis - Eigen::Vector3d::UnitZ()).norm() < 1e-15;
  if (j.mimic) {
    if (!std::isfinite(j.mimic->multiplier) || !std::isfinite(j.mimic->offset))
      throw std::invalid_argument("URDF '" + source + "': joint '" + j.name +
                                  "': mimic multiplier and offset must be finite");
    link.mimic.multiplier = j.mimic->multiplier;
    link.mimic.offset = j.mimic->offset;
    link.mimic.source_q = -2;  // resolved once every joint has an index
  }
}

struct JointLimits {
  double lower, upper, velocity;
};

// A moving joint's position limits (none for continuous joints) and velocity limit (inf: none given).
JointLimits read_limits(const urdf::Joint& j, JointType type, const std::string& source) {
  const double inf = std::numeric_limits<double>::infinity();
  JointLimits out{-inf, inf, inf};
  if (j.limits && type != JointType::Continuous) {
    out.lower = j.limits->lower;
    out.upper = j.limits->upper;
    if (!(std::isfinite(out.lower) && std::isfinite(out.upper) && out.lower <= out.upper))
      throw std::invalid_argument("URDF '" + source + "': joint '" + j.name + "' has limits lower " +
                                  std::to_string(out.lower) + " > upper " + std::to_string(out.upper) +
                                  " (or not finite); expected lower <= upper");
  }
  if (j.limits && j.limits->velocity > 0) out.velocity = j.limits->velocity;
  return out;
}

// One <collision> of link `link_name`: a mesh (its file resolved) or a primitive, sizes checked.
CollisionGeometry read_collision(const urdf::Collision& col, const std::string& link_name, const std::string& base_dir,
                                 const std::vector<std::string>& package_dirs, const std::string& source) {
  CollisionGeometry g;
  require_finite_pose(source, "collision of link '" + link_name + "'", col.origin);
  g.origin = to_transform(col.origin);
  switch (col.geometry->type) {
    case urdf::Geometry::MESH: {
      auto mesh = std::static_pointer_cast<const urdf::Mesh>(col.geometry);
      g.kind = CollisionGeometry::Kind::Mesh;
      g.mesh_path = resolve_mesh(mesh->filename, base_dir, package_dirs);
      if (g.mesh_path.empty())
        throw FileNotFound("URDF '" + source + "': collision mesh '" + mesh->filename + "' of link '" + link_name +
                           "' not found (searched relative to '" + base_dir + "' and the package directories)");
      g.scale = Eigen::Vector3d(mesh->scale.x, mesh->scale.y, mesh->scale.z);
      for (int a = 0; a < 3; ++a)
        if (!(std::isfinite(g.scale[a]) && g.scale[a] != 0.0))
          throw std::invalid_argument("URDF '" + source + "': link '" + link_name +
                                      "': mesh scale must be finite and non-zero");
      break;
    }
    case urdf::Geometry::BOX: {
      auto box = std::static_pointer_cast<const urdf::Box>(col.geometry);
      g.kind = CollisionGeometry::Kind::Box;
      g.size = Eigen::Vector3d(box->dim.x, box->dim.y, box->dim.z);
      for (int a = 0; a < 3; ++a) require_positive(source, link_name, "box size", g.size[a]);
      break;
    }
    case urdf::Geometry::CYLINDER: {
      auto cyl = std::static_pointer_cast<const urdf::Cylinder>(col.geometry);
      g.kind = CollisionGeometry::Kind::Cylinder;
      g.size = Eigen::Vector3d(cyl->radius, cyl->length, 0.0);
      require_positive(source, link_name, "cylinder radius", cyl->radius);
      require_positive(source, link_name, "cylinder length", cyl->length);
      break;
    }
    case urdf::Geometry::SPHERE: {
      auto sph = std::static_pointer_cast<const urdf::Sphere>(col.geometry);
      g.kind = CollisionGeometry::Kind::Sphere;
      g.size = Eigen::Vector3d(sph->radius, 0.0, 0.0);
      require_positive(source, link_name, "sphere radius", sph->radius);
      break;
    }
  }
  return g;
}

}  // namespace

void require_rigid(const char* what, const Eigen::Matrix4d& M, double tol) {
  require_finite(what, M.data(), 16);
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double orth = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double last = (M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff();
  if (orth > tol || std::abs(R.determinant() - 1.0) > tol || last > tol) {
    std::ostringstream msg;
    msg << what << ": not a rigid transform (rotation orthonormality error " << orth << ", determinant "
        << R.determinant() << ", last row error " << last << ")";
    throw std::invalid_argument(msg.str());
  }
}

Eigen::Matrix4d cleaned_rigid(const char* what, const Eigen::Matrix4d& M, double tol) {
  require_rigid(what, M, tol);
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(M.topLeftCorner<3, 3>(), Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix4d out = M;
  out.topLeftCorner<3, 3>() = svd.matrixU() * svd.matrixV().transpose();
  out.row(3) << 0, 0, 0, 1;
  return out;
}

RobotWorkspace::RobotWorkspace(const Robot& robot)
    : link_pose(robot.num_links()), axis_world(robot.num_links(), Eigen::Vector3d::Zero()) {}

Robot Robot::from_urdf_file(const std::string& path, const std::vector<std::string>& package_dirs) {
  const std::string xml = read_file(path);
  return from_urdf_string(xml, fs::absolute(path).parent_path().string(), package_dirs, path);
}

Robot Robot::from_urdf_string(const std::string& xml, const std::string& base_dir,
                              const std::vector<std::string>& package_dirs, const std::string& source) {
  const urdf::ModelInterfaceSharedPtr model = parse_urdf_model(xml, source);
  const auto order = joint_document_order(xml);
  auto rank = [&](const urdf::LinkConstSharedPtr& l) {
    auto it = l->parent_joint ? order.find(l->parent_joint->name) : order.end();
    return it == order.end() ? static_cast<int>(order.size()) : it->second;
  };

  Robot robot;
  robot.name_ = model->getName();
  std::map<std::string, int> q_of_joint;
  // Depth-first from the root so parents precede children.
  std::vector<std::pair<urdf::LinkConstSharedPtr, int>> stack{{model->getRoot(), -1}};
  while (!stack.empty()) {
    auto [ulink, parent] = stack.back();
    stack.pop_back();
    Link link;
    link.name = ulink->name;
    link.parent = parent;
    if (const auto& j = ulink->parent_joint) {
      read_joint(*j, source, link);
      if (link.joint_type != JointType::Fixed) {
        link.q_index = static_cast<int>(robot.joint_names_.size());
        q_of_joint[j->name] = link.q_index;
        robot.joint_names_.push_back(j->name);
        const JointLimits limits = read_limits(*j, link.joint_type, source);
        robot.lower_.conservativeResize(link.q_index + 1);
        robot.upper_.conservativeResize(link.q_index + 1);
        robot.velocity_.conservativeResize(link.q_index + 1);
        robot.lower_[link.q_index] = limits.lower;
        robot.upper_[link.q_index] = limits.upper;
        robot.velocity_[link.q_index] = limits.velocity;
      }
    }
    for (const auto& col : ulink->collision_array)
      if (col && col->geometry)
        link.collisions.push_back(read_collision(*col, ulink->name, base_dir, package_dirs, source));
    const int index = static_cast<int>(robot.links_.size());
    robot.links_.push_back(std::move(link));
    std::vector<urdf::LinkConstSharedPtr> children(ulink->child_links.begin(), ulink->child_links.end());
    std::sort(children.begin(), children.end(), [&](const auto& a, const auto& b) { return rank(a) > rank(b); });
    for (const auto& child : children) stack.emplace_back(child, index);
  }
  // Resolve mimic sources now that all joints are numbered.
  for (auto& link : robot.links_) {
    if (link.mimic.source_q != -2) continue;
    std::string src;
    for (const auto& ulink_pair : model->joints_)
      if (ulink_pair.first == link.joint_name && ulink_pair.second->mimic) src = ulink_pair.second->mimic->joint_name;
    auto it = q_of_joint.find(src);
    link.mimic.source_q = it == q_of_joint.end() ? -1 : it->second;
  }
  robot.finalize();
  return robot;
}

void Robot::finalize() {
  link_names_.clear();
  q_link_.assign(dof(), -1);
  for (int i = 0; i < num_links(); ++i) {
    link_names_.push_back(links_[i].name);
    if (links_[i].q_index >= 0) q_link_[links_[i].q_index] = i;
  }
  chain_mask_.assign(static_cast<size_t>(num_links()) * dof(), 0);
  for (int i = 0; i < num_links(); ++i)
    for (int k = i; k >= 0; k = links_[k].parent)
      if (links_[k].q_index >= 0) chain_mask_[i * dof() + links_[k].q_index] = 1;
  if (lower_.size() != dof()) {
    lower_.resize(dof());
    upper_.resize(dof());
    velocity_.resize(dof());
  }
}

Robot Robot::with_base(const Transform& base) const {
  Robot copy = *this;
  copy.base_ = base;
  return copy;
}

Robot Robot::with_attached_link(const std::string& name, const std::string& parent, const Transform& origin) const {
  if (name.empty()) throw std::invalid_argument("attached link: the name must not be empty");
  for (const auto& l : links_)
    if (l.name == name) throw std::invalid_argument("attached link: a link named '" + name + "' exists already");
  require_rigid("attached link origin", origin.matrix(), 1e-6);
  Link link;
  link.name = name;
  link.parent = link_index(parent);  // throws, naming the links
  link.joint_name = name + "_attachment";
  link.joint_type = JointType::Fixed;
  link.joint_origin = origin;
  Robot copy = *this;
  copy.links_.push_back(std::move(link));
  copy.finalize();
  return copy;
}

int Robot::link_index(const std::string& name) const {
  for (int i = 0; i < num_links(); ++i)
    if (links_[i].name == name) return i;
  std::string all;
  for (const auto& n : link_names_) all += (all.empty() ? "" : ", ") + n;
  throw std::invalid_argument("unknown link '" + name + "'; links are: " + all);
}

void Robot::check_configuration(const double* q, long n) const {
  require_size("configuration", dof(), n, "joint values");
  require_finite("configuration", q, n);
}

void Robot::forward_kinematics(const double* q, RobotWorkspace& ws, int last) const {
  const int n = std::min(last + 1, num_links());
  for (int i = 0; i < n; ++i) {
    const Link& L = links_[i];
    const Transform& parent = L.parent < 0 ? base_ : ws.link_pose[L.parent];
    Transform& T = ws.link_pose[i];
    T = parent * L.joint_origin;
    if (L.q_index < 0) continue;
    ws.axis_world[i].noalias() = T.R * L.axis;  // the joint's own motion leaves its axis fixed
    const double v = q[L.q_index];
    if (L.joint_type == JointType::Prismatic) {
      T.p.noalias() += T.R * (L.axis * v);
    } else if (L.axis_is_z) {  // R * Rz(v): only the first two columns change
      const double c = std::cos(v), s = std::sin(v);
      const Eigen::Vector3d c0 = T.R.col(0), c1 = T.R.col(1);
      T.R.col(0) = c * c0 + s * c1;
      T.R.col(1) = c * c1 - s * c0;
    } else {
      T.R = T.R * axis_angle(L.axis, v);
    }
  }
}

void Robot::point_jacobian(const RobotWorkspace& ws, int link, const Eigen::Vector3d& point_local,
                           Eigen::Ref<Eigen::Matrix<double, 6, Eigen::Dynamic>> J) const {
  require_size("point Jacobian", dof(), J.cols(), "columns");
  J.setZero();
  const Eigen::Vector3d x = ws.link_pose[link].apply(point_local);
  for (int k = link; k >= 0; k = links_[k].parent) {
    const Link& L = links_[k];
    if (L.q_index < 0) continue;
    const Transform& T = ws.link_pose[k];
    const Eigen::Vector3d& a = ws.axis_world[k];
    if (L.joint_type == JointType::Prismatic) {
      J.block<3, 1>(0, L.q_index) = a;
    } else {
      J.block<3, 1>(0, L.q_index) = a.cross(x - T.p);
      J.block<3, 1>(3, L.q_index) = a;
    }
  }
}

void Robot::position_jacobian_world(const RobotWorkspace& ws, int link, const Eigen::Vector3d& x,
                                    Eigen::Ref<Eigen::Matrix<double, 3, Eigen::Dynamic>> J) const {
  require_size("position Jacobian", dof(), J.cols(), "columns");
  J.setZero();
  for (int k = link; k >= 0; k = links_[k].parent) {
    const Link& L = links_[k];
    if (L.q_index < 0) continue;
    const Transform& T = ws.link_pose[k];
    const Eigen::Vector3d& a = ws.axis_world[k];
    J.col(L.q_index) = L.joint_type == JointType::Prismatic ? a : Eigen::Vector3d(a.cross(x - T.p));
  }
}

void Robot::add_wrench_jacobian_transpose(const RobotWorkspace& ws, int link, const Eigen::Vector3d& force,
                                          const Eigen::Vector3d& moment, double* out) const {
  for (int k = link; k >= 0; k = links_[k].parent) {
    const Link& L = links_[k];
    if (L.q_index < 0) continue;
    const Eigen::Vector3d& a = ws.axis_world[k];
    // sum_i (a x (x_i - p)) . f_i = a . sum_i (x_i - p) x f_i = a . (M - p x F)
    out[L.q_index] +=
        L.joint_type == JointType::Prismatic ? a.dot(force) : a.dot(moment - ws.link_pose[k].p.cross(force));
  }
}

}  // namespace pickplan::core
