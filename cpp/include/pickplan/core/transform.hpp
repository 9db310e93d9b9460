#pragma once
// A rigid transform as rotation + translation: cheaper to compose than a 4x4 matrix.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace pickplan::core {

struct Transform {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  Eigen::Vector3d p = Eigen::Vector3d::Zero();

  static Transform identity() { return Transform{}; }
  static Transform from_matrix(const Eigen::Matrix4d& M) {
    Transform T;
    T.R = M.topLeftCorner<3, 3>();
    T.p = M.topRightCorner<3, 1>();
    return T;
  }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d M = Eigen::Matrix4d::Identity();
    M.topLeftCorner<3, 3>() = R;
    M.topRightCorner<3, 1>() = p;
    return M;
  }
  Transform operator*(const Transform& o) const {
    Transform T;
    T.R.noalias() = R * o.R;
    T.p.noalias() = R * o.p;
    T.p += p;
    return T;
  }
  Eigen::Vector3d apply(const Eigen::Vector3d& x) const { return R * x + p; }
  Transform inverse() const {
    Transform T;
    T.R = R.transpose();
    T.p = -(T.R * p);
    return T;
  }
};

// Rotation by angle about a unit axis (Rodrigues).
inline Eigen::Matrix3d axis_angle(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis).toRotationMatrix();
}

// Throws std::invalid_argument when M is not a rigid transform (orthonormal, det +1, last row 0 0 0 1).
void require_rigid(const char* what, const Eigen::Matrix4d& M, double tol = 1e-6);

// How far from rigid a pose read from a file may be and still be cleaned: real data stored in
// float32 (the YCB graspit sets) is off by ~1.6e-6; past this the pose is rejected, not repaired.
constexpr double kRigidCleanTolerance = 1e-4;

// M with its rotation projected onto SO(3) and its last row set to 0 0 0 1, when M is rigid within
// `tol` (orthonormality, determinant, last row); std::invalid_argument naming `what` otherwise.
Eigen::Matrix4d cleaned_rigid(const char* what, const Eigen::Matrix4d& M, double tol = kRigidCleanTolerance);

}  // namespace pickplan::core
