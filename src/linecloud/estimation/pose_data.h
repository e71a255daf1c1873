// The correspondences of one query with a map, in the frames the minimal
// solvers and the refinement use, and the reprojection residuals of
// Speciale et al., CVPR 2019: eq. 2 (point-to-point) for point maps and
// eq. 6 (distance of the observation to the projected line) for line clouds,
// both in pixels, with their analytic Jacobians.
#pragma once

#include <cstddef>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

struct PoseData {
  std::vector<Rigid3d> cam_from_rig;        // one per camera; identity for one image
  std::vector<int> camera;                  // camera of each correspondence
  std::vector<Eigen::Vector2d> normalized;  // undistorted image point (x/z, y/z)
  std::vector<double> focal;                // pixels per normalised unit, per correspondence
  std::vector<Eigen::Vector3d> bearings;    // unit, camera frame
  std::vector<Eigen::Vector3d> points_local;  // +l: X̃ in the rig frame
  std::vector<Eigen::Vector3d> points;      // point map (empty for a line map)
  std::vector<PluckerLine> lines;           // line map (empty for a point map)

  size_t size() const { return camera.size(); }
  bool has_lines() const { return !lines.empty(); }
};

// Per-camera cam_from_world (Sim3: scale of query_from_world) for one pose.
struct CameraPoses {
  std::vector<Eigen::Matrix3d> rotation;
  std::vector<Eigen::Vector3d> translation;
  double scale = 1;

  CameraPoses(const PoseData& data, const Sim3d& query_from_world);
};

// Squared reprojection error of correspondence i in px²; +∞ when the point is
// behind its camera or, for a line within 100 px of the observation, when the
// line passes behind the camera where the viewing ray comes closest to it.
double SquaredReprojectionError(const PoseData& data, const CameraPoses& poses, size_t i);

// A pose with its rotation matrices computed once, for evaluating many
// residuals.
struct PoseLinearization {
  Eigen::Matrix3d rotation;                      // of query_from_world
  Eigen::Vector3d translation;
  double scale = 1;
  std::vector<Eigen::Matrix3d> cam_rotation;     // of cam_from_rig, per camera

  PoseLinearization(const PoseData& data, const Sim3d& query_from_world);
};

// Residuals of correspondence i (2 for a point, 1 for a line, in px) and their
// Jacobian with respect to a left perturbation of query_from_world:
// R ← exp([ω]×) R, t ← t + δt, s ← s·exp(δσ), columns (ω, δt, δσ).
// Returns the number of residuals, 0 if the point is behind its camera; for a
// line the second residual and Jacobian row are zero.
int ReprojectionResidual(const PoseData& data, const PoseLinearization& pose, size_t i,
                         Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 7>* jacobian);
inline int ReprojectionResidual(const PoseData& data, const Sim3d& query_from_world, size_t i,
                                Eigen::Vector2d* residual,
                                Eigen::Matrix<double, 2, 7>* jacobian) {
  return ReprojectionResidual(data, PoseLinearization(data, query_from_world), i, residual,
                              jacobian);
}

}  // namespace linecloud
