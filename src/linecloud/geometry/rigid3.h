// Rigid and similarity transforms, named target_from_source as in COLMAP:
// x_cam = cam_from_world * x_world = R x_world + t. Quaternions are (w, x, y, z).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace linecloud {

struct Rigid3d {
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Rigid3d() = default;
  Rigid3d(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : rotation(q), translation(t) {}

  Eigen::Matrix<double, 3, 4> ToMatrix() const {
    Eigen::Matrix<double, 3, 4> m;
    m.leftCols<3>() = rotation.toRotationMatrix();
    m.col(3) = translation;
    return m;
  }

  Rigid3d Inverse() const {
    const Eigen::Quaterniond inv = rotation.inverse();
    return Rigid3d(inv, -(inv * translation));
  }

  // The target frame's origin expressed in the source frame, -R^T t (for
  // cam_from_world: the camera centre in world coordinates).
  Eigen::Vector3d Center() const { return -(rotation.inverse() * translation); }

  // Exactly the identity (a rig's reference camera), whatever the quaternion's sign.
  bool IsIdentity() const { return translation.isZero(0) && rotation.vec().isZero(0); }
};

inline Eigen::Vector3d operator*(const Rigid3d& t, const Eigen::Vector3d& x) {
  return t.rotation * x + t.translation;
}

// c_from_a = c_from_b * b_from_a.
inline Rigid3d operator*(const Rigid3d& c_from_b, const Rigid3d& b_from_a) {
  return Rigid3d((c_from_b.rotation * b_from_a.rotation).normalized(),
                 c_from_b.rotation * b_from_a.translation + c_from_b.translation);
}

// x_target = s R x_source + t, s > 0.
struct Sim3d {
  double scale = 1.0;
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();

  Sim3d() = default;
  Sim3d(double s, const Eigen::Quaterniond& q, const Eigen::Vector3d& t)
      : scale(s), rotation(q), translation(t) {}

  Sim3d Inverse() const {
    const Eigen::Quaterniond inv = rotation.inverse();
    return Sim3d(1.0 / scale, inv, -(inv * translation) / scale);
  }
};

// A rigid transform as a similarity of scale 1.
inline Sim3d ToSim3(const Rigid3d& p) { return Sim3d(1.0, p.rotation, p.translation); }

inline Eigen::Vector3d operator*(const Sim3d& t, const Eigen::Vector3d& x) {
  return t.scale * (t.rotation * x) + t.translation;
}

inline Sim3d operator*(const Sim3d& c_from_b, const Sim3d& b_from_a) {
  return Sim3d(c_from_b.scale * b_from_a.scale,
               (c_from_b.rotation * b_from_a.rotation).normalized(),
               c_from_b.scale * (c_from_b.rotation * b_from_a.translation) + c_from_b.translation);
}

// Angle of the rotation between two orientations, in radians.
inline double RotationDistance(const Eigen::Quaterniond& a, const Eigen::Quaterniond& b) {
  return a.angularDistance(b);
}

}  // namespace linecloud
