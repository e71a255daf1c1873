#include "linecloud/estimation/pose_data.h"

#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace linecloud {
namespace {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

// Whether the line (a + α v, |v| = 1) comes closest to the viewing ray d
// (through the camera centre) in front of the camera. Nearly parallel pairs
// pass: the closest point is then ill-defined.
bool LineInFront(const Eigen::Vector3d& anchor, const Eigen::Vector3d& v,
                 const Eigen::Vector3d& d) {
  const double vd = v.dot(d);
  const double denom = 1 - vd * vd;
  if (denom < 1e-12) return true;
  const double depth = (anchor.dot(d) - anchor.dot(v) * vd) / denom;
  return depth > 0;
}

}  // namespace

CameraPoses::CameraPoses(const PoseData& data, const Sim3d& query_from_world)
    : scale(query_from_world.scale) {
  const Eigen::Matrix3d r = query_from_world.rotation.toRotationMatrix();
  rotation.reserve(data.cam_from_rig.size());
  translation.reserve(data.cam_from_rig.size());
  for (const Rigid3d& cam_from_rig : data.cam_from_rig) {
    const Eigen::Matrix3d rc = cam_from_rig.rotation.toRotationMatrix();
    rotation.push_back(rc * r);
    translation.push_back(rc * query_from_world.translation + cam_from_rig.translation);
  }
}

double SquaredReprojectionError(const PoseData& data, const CameraPoses& poses, size_t i) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int c = data.camera[i];
  const Eigen::Matrix3d& r = poses.rotation[c];
  const Eigen::Vector3d& t = poses.translation[c];
  const Eigen::Vector2d& x = data.normalized[i];
  const double f = data.focal[i];
  if (data.has_lines()) {
    const PluckerLine& l = data.lines[i];
    const Eigen::Vector3d v = r * l.v;
    const Eigen::Vector3d w = poses.scale * (r * l.w) + t.cross(v);
    const double n2 = w.x() * w.x() + w.y() * w.y();
    if (!(n2 > 0)) return kInf;
    const Eigen::Vector3d ray(x.x(), x.y(), 1.0);
    if (!LineInFront(v.cross(w), v, ray.normalized())) return kInf;
    const double e = w.dot(ray);
    return f * f * e * e / n2;
  }
  const Eigen::Vector3d p = poses.scale * (r * data.points[i]) + t;
  if (!(p.z() > 0)) return kInf;
  return f * f * (p.head<2>() / p.z() - x).squaredNorm();
}

int ReprojectionResidual(const PoseData& data, const Sim3d& pose, size_t i,
                         Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 7>* jacobian) {
  const Rigid3d& cam_from_rig = data.cam_from_rig[data.camera[i]];
  const Eigen::Matrix3d rc = cam_from_rig.rotation.toRotationMatrix();
  const Eigen::Matrix3d r = pose.rotation.toRotationMatrix();
  const double s = pose.scale;
  const Eigen::Vector2d& x = data.normalized[i];
  const double f = data.focal[i];
  if (data.has_lines()) {
    // Moved line: v' = R v, w' = s R w + t × R v; in the camera:
    // v'' = R_c v', w'' = R_c w' + t_c × v''. Residual f (w''·x̄) / |w''_xy|.
    const PluckerLine& l = data.lines[i];
    const Eigen::Vector3d rv = r * l.v, rw = r * l.w;
    const Eigen::Vector3d w1 = s * rw + pose.translation.cross(rv);
    const Eigen::Vector3d v2 = rc * rv;
    const Eigen::Vector3d w2 = rc * w1 + cam_from_rig.translation.cross(v2);
    const double n = std::hypot(w2.x(), w2.y());
    if (!(n > 0)) return 0;
    const Eigen::Vector3d ray(x.x(), x.y(), 1.0);
    const double e = w2.dot(ray);
    (*residual)[0] = f * e / n;
    if (jacobian != nullptr) {
      Eigen::Matrix<double, 3, 7> dw1, dv1 = Eigen::Matrix<double, 3, 7>::Zero();
      dv1.leftCols<3>() = -Hat(rv);
      dw1.leftCols<3>() = -s * Hat(rw) - Hat(pose.translation) * Hat(rv);
      dw1.middleCols<3>(3) = -Hat(rv);
      dw1.col(6) = s * rw;
      const Eigen::Matrix<double, 3, 7> dw2 =
          rc * dw1 + Hat(cam_from_rig.translation) * rc * dv1;
      const Eigen::RowVector3d de_dw =
          f * (ray.transpose() / n -
               e * Eigen::RowVector3d(w2.x(), w2.y(), 0) / (n * n * n));
      jacobian->setZero();
      jacobian->row(0) = de_dw * dw2;
    }
    return 1;
  }
  // Point: Y = s R X + t, Z = R_c Y + t_c, residual f (Z_xy / Z_z − x).
  const Eigen::Vector3d srx = s * (r * data.points[i]);
  const Eigen::Vector3d z = rc * (srx + pose.translation) + cam_from_rig.translation;
  if (!(z.z() > 0)) return 0;
  *residual = f * (z.head<2>() / z.z() - x);
  if (jacobian != nullptr) {
    Eigen::Matrix<double, 3, 7> dy;
    dy.leftCols<3>() = -Hat(srx);
    dy.middleCols<3>(3).setIdentity();
    dy.col(6) = srx;
    Eigen::Matrix<double, 2, 3> dproj;
    dproj << 1 / z.z(), 0, -z.x() / (z.z() * z.z()), 0, 1 / z.z(), -z.y() / (z.z() * z.z());
    *jacobian = f * dproj * rc * dy;
  }
  return 2;
}

}  // namespace linecloud
