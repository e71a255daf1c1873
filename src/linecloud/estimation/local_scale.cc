#include "linecloud/estimation/local_scale.h"

#include <cmath>

#include "linecloud/util/error.h"

namespace linecloud {

namespace {

// bᵢ and dᵢ of the header for the camera-centred pose (rotation R, world
// centre C, rig-frame centre c).
void LinearResidual(const PoseData& data, int i, const Eigen::Matrix3d& rotation,
                    const Eigen::Vector3d& centre_world, const Eigen::Vector3d& centre_rig,
                    Eigen::Vector3d* b, Eigen::Vector3d* d) {
  const Eigen::Vector3d local = data.points_local[i] - centre_rig;
  if (data.has_lines()) {
    const PluckerLine& line = data.lines[i];
    const Eigen::Vector3d v = rotation * line.v.normalized();
    *b = local.cross(v);
    *d = (rotation * (line.Anchor() - centre_world)).cross(v);
  } else {
    *b = local;
    *d = rotation * (data.points[i] - centre_world);
  }
}

}  // namespace

Eigen::Vector3d LocalPointResidual(const PoseData& data, int i, const Sim3d& query_from_world) {
  const Eigen::Vector3d& local = data.points_local.at(i);
  if (data.has_lines()) {
    const PluckerLine& line = data.lines[i];
    const Eigen::Vector3d v = query_from_world.rotation * line.v.normalized();
    return (local - query_from_world * line.Anchor()).cross(v);
  }
  return local - query_from_world * data.points[i];
}

bool SeenByOneCamera(const PoseData& data, std::span<const int> indices) {
  for (const int i : indices) {
    if (data.camera[i] != data.camera[indices.front()]) return false;
  }
  return true;
}

std::optional<LocalScaleFit> FitScaleToLocalPoints(const PoseData& data,
                                                   std::span<const int> indices,
                                                   Sim3d* query_from_world) {
  data.Check("FitScaleToLocalPoints");
  CheckIndices(data, indices, "FitScaleToLocalPoints");
  if (data.points_local.empty() || indices.size() < 2) return std::nullopt;
  const Sim3d& pose = *query_from_world;
  const Rigid3d& cam_from_rig = data.cam_from_rig.at(data.camera[indices.front()]);
  const Eigen::Vector3d centre_rig = cam_from_rig.Inverse().translation;
  const Eigen::Vector3d centre_world = pose.Inverse() * centre_rig;
  const Eigen::Matrix3d rotation = pose.rotation.toRotationMatrix();
  double bd = 0, dd = 0;
  for (const int i : indices) {
    Eigen::Vector3d b, d;
    LinearResidual(data, i, rotation, centre_world, centre_rig, &b, &d);
    bd += b.dot(d);
    dd += d.squaredNorm();
  }
  if (!(dd > 0)) return std::nullopt;
  const double scale = bd / dd;
  if (!(scale > 0) || !std::isfinite(scale)) return std::nullopt;
  double sum_sq = 0;
  for (const int i : indices) {
    Eigen::Vector3d b, d;
    LinearResidual(data, i, rotation, centre_world, centre_rig, &b, &d);
    sum_sq += (b - scale * d).squaredNorm();
  }
  const int dof = static_cast<int>(indices.size()) * (data.has_lines() ? 2 : 3) - 1;
  LocalScaleFit fit;
  fit.scale_before = pose.scale;
  fit.sigma_local = std::sqrt(sum_sq / dof);
  fit.log_scale_se = fit.sigma_local / (scale * std::sqrt(dd));
  // s R (x − C) + c = s R x + (c − s R C).
  *query_from_world = Sim3d(scale, pose.rotation, centre_rig - scale * (rotation * centre_world));
  return fit;
}

}  // namespace linecloud
