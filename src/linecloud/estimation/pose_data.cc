#include "linecloud/estimation/pose_data.h"

#include "linecloud/util/error.h"

#include <cmath>
#include <limits>

#include <Eigen/Geometry>

namespace linecloud {

void PoseData::Check(const char* where) const {
  const size_t n = camera.size();
  const auto same = [&](size_t size, const char* name) {
    if (size != n) Fail("{}: pose data has {} cameras but {} {}", where, n, size, name);
  };
  same(normalized.size(), "normalized points");
  same(focal.size(), "focal lengths");
  same(bearings.size(), "bearings");
  if (!points_local.empty()) same(points_local.size(), "local points");
  if (!points.empty() && !lines.empty()) Fail("{}: pose data has both points and lines", where);
  same(lines.empty() ? points.size() : lines.size(), lines.empty() ? "points" : "lines");
  if (!ranking.empty()) same(ranking.size(), "ranked entries");
  for (size_t i = 0; i < n; ++i) {
    if (camera[i] < 0 || static_cast<size_t>(camera[i]) >= cam_from_rig.size()) {
      Fail("{}: correspondence {} has camera {} but there are {} cameras", where, i, camera[i],
           cam_from_rig.size());
    }
  }
  for (const int r : ranking) {
    if (r < 0 || static_cast<size_t>(r) >= n) Fail("{}: ranking entry {} out of range", where, r);
  }
}

void CheckIndices(const PoseData& data, std::span<const int> indices, const char* where) {
  for (const int i : indices) {
    if (i < 0 || static_cast<size_t>(i) >= data.size()) {
      Fail("{}: correspondence index {} out of range [0, {})", where, i, data.size());
    }
  }
}
namespace {

Eigen::Matrix3d Hat(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
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
    scaled_rotation.push_back(scale * rotation.back());
    moment_from_v.push_back(Hat(translation.back()) * rotation.back());
  }
}

double MeanReprojectionError(const PoseData& data, const Sim3d& query_from_world,
                             std::span<const int> indices) {
  CheckIndices(data, indices, "MeanReprojectionError");
  const CameraPoses poses(data, query_from_world);
  double sum = 0;
  size_t n = 0;
  for (const int i : indices) {
    const double e2 = SquaredReprojectionError(data, poses, static_cast<size_t>(i));
    if (!std::isfinite(e2)) continue;
    sum += std::sqrt(e2);
    ++n;
  }
  return n ? sum / static_cast<double>(n) : 0.0;
}

PoseLinearization::PoseLinearization(const PoseData& data, const Sim3d& query_from_world)
    : rotation(query_from_world.rotation.toRotationMatrix()),
      translation(query_from_world.translation),
      scale(query_from_world.scale) {
  cam_rotation.reserve(data.cam_from_rig.size());
  for (const Rigid3d& p : data.cam_from_rig) cam_rotation.push_back(p.rotation.toRotationMatrix());
}

int ReprojectionResidual(const PoseData& data, const PoseLinearization& pose, size_t i,
                         Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 7>* jacobian) {
  const Rigid3d& cam_from_rig = data.cam_from_rig[data.camera[i]];
  const Eigen::Matrix3d& rc = pose.cam_rotation[data.camera[i]];
  const Eigen::Matrix3d& r = pose.rotation;
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
    const double n = std::sqrt(w2.x() * w2.x() + w2.y() * w2.y());
    if (!(n > 0)) return 0;
    const Eigen::Vector3d ray(x.x(), x.y(), 1.0);
    const double e = w2.dot(ray);
    *residual = Eigen::Vector2d(f * e / n, 0.0);  // second entry unused
    // The line passes behind the camera where the viewing ray comes closest:
    // as SquaredReprojectionError, for residuals that could be inliers.
    if ((*residual)[0] * (*residual)[0] < kCheiralityBelow &&
        !internal::LineInFront(v2.cross(w2), v2, data.bearings[i])) {
      return 0;
    }
    if (jacobian != nullptr) {
      // e = a·w'' with a = ∂e/∂w''. With b = R_cᵀ a and c = R_cᵀ (a × t_c):
      // de = b·dw' + c·dv', dv' = ω × Rv, dw' = s ω × Rw + δt × Rv +
      // t × (ω × Rv) + δσ s Rw; each term rewritten as a gradient.
      const Eigen::Vector3d a =
          f * (ray / n - e * Eigen::Vector3d(w2.x(), w2.y(), 0) / (n * n * n));
      const Eigen::Vector3d b = rc.transpose() * a;
      const Eigen::Vector3d c = rc.transpose() * a.cross(cam_from_rig.translation);
      const Eigen::Vector3d bt = b.cross(pose.translation);
      jacobian->setZero();
      jacobian->block<1, 3>(0, 0) = (-s * b.cross(rw) - bt.cross(rv) - c.cross(rv)).transpose();
      jacobian->block<1, 3>(0, 3) = -b.cross(rv).transpose();
      (*jacobian)(0, 6) = s * b.dot(rw);
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
