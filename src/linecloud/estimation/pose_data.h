// The correspondences of one query with a map, in the frames the minimal
// solvers and the refinement use, and the reprojection residuals of
// Speciale et al., CVPR 2019: eq. 2 (point-to-point) for point maps and
// eq. 6 (distance of the observation to the projected line) for line clouds,
// both in pixels, with their analytic Jacobians.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// Cheirality of a line is only tested for residuals below this (px²):
// larger ones are outliers to any caller anyway.
constexpr double kCheiralityBelow = 1e4;

struct PoseData {
  std::vector<Rigid3d> cam_from_rig;          // one per camera; identity for one image
  std::vector<int> camera;                    // camera of each correspondence
  std::vector<Eigen::Vector2d> normalized;    // undistorted image point (x/z, y/z)
  std::vector<double> focal;                  // pixels per normalised unit, per correspondence
  std::vector<Eigen::Vector3d> bearings;      // unit, camera frame
  std::vector<Eigen::Vector3d> points_local;  // +l: X̃ in the rig frame
  std::vector<Eigen::Vector3d> points;        // point map (empty for a line map)
  std::vector<PluckerLine> lines;             // line map (empty for a point map)
  // Correspondence indices by match quality, best first (PROSAC); empty when
  // the matches have no scores.
  std::vector<int> ranking;

  size_t size() const { return camera.size(); }
  bool has_lines() const { return !lines.empty(); }

  // Precondition of the public entry points that take PoseData (PoseEstimator,
  // RefinePose, the uncertainty): one entry per correspondence in every
  // per-correspondence array, points or lines (not both), camera indices
  // within cam_from_rig, a ranking of every correspondence or none. Throws
  // Error naming `where`.
  void Check(const char* where) const;
};

// Every index in [0, data.size()); throws Error naming `where`.
void CheckIndices(const PoseData& data, std::span<const int> indices, const char* where);

// Per-camera cam_from_world (Sim3: scale of query_from_world) for one pose.
struct CameraPoses {
  std::vector<Eigen::Matrix3d> rotation;         // R_C = R_c R
  std::vector<Eigen::Vector3d> translation;      // t_C = R_c t + t_c
  std::vector<Eigen::Matrix3d> scaled_rotation;  // s R_C
  std::vector<Eigen::Matrix3d> moment_from_v;    // [t_C]× R_C: w_cam = s R_C w + [t_C]× R_C v
  double scale = 1;

  CameraPoses(const PoseData& data, const Sim3d& query_from_world);
};

// Squared reprojection error of correspondence i in px²; +∞ when the point is
// behind its camera or when the line passes behind the camera where the
// viewing ray comes closest to it. That line test is skipped for errors of at
// least `cheirality_below` px² (outliers to the caller anyway).
// (Inline below: RANSAC scores every correspondence of every model with it.)
inline double SquaredReprojectionError(const PoseData& data, const CameraPoses& poses, size_t i,
                                       double cheirality_below = kCheiralityBelow);

// A pose with its rotation matrices computed once, for evaluating many
// residuals.
struct PoseLinearization {
  Eigen::Matrix3d rotation;  // of query_from_world
  Eigen::Vector3d translation;
  double scale = 1;
  std::vector<Eigen::Matrix3d> cam_rotation;  // of cam_from_rig, per camera

  PoseLinearization(const PoseData& data, const Sim3d& query_from_world);
};

// Mean reprojection error (px) of the correspondences `indices` at the pose;
// those it puts behind their camera (no image position, +∞ above) are left
// out, like the secret points of the evaluation. 0 when none is left.
double MeanReprojectionError(const PoseData& data, const Sim3d& query_from_world,
                             std::span<const int> indices);

// Residuals of correspondence i (2 for a point, 1 for a line, in px) and their
// Jacobian with respect to a left perturbation of query_from_world:
// R ← exp([ω]×) R, t ← t + δt, s ← s·exp(δσ), columns (ω, δt, δσ).
// Returns the number of residuals, 0 if the point is behind its camera or the
// line passes behind it (the test of SquaredReprojectionError, for residuals
// below kCheiralityBelow); for a line the second residual and Jacobian row are
// zero.
int ReprojectionResidual(const PoseData& data, const PoseLinearization& pose, size_t i,
                         Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 7>* jacobian);
inline int ReprojectionResidual(const PoseData& data, const Sim3d& query_from_world, size_t i,
                                Eigen::Vector2d* residual, Eigen::Matrix<double, 2, 7>* jacobian) {
  return ReprojectionResidual(data, PoseLinearization(data, query_from_world), i, residual,
                              jacobian);
}

namespace internal {
// Whether the line (a + α v, |v| = 1) comes closest to the viewing ray d
// (through the camera centre) in front of the camera. Nearly parallel pairs
// pass: the closest point is then ill-defined.
inline bool LineInFront(const Eigen::Vector3d& anchor, const Eigen::Vector3d& v,
                        const Eigen::Vector3d& d) {
  const double vd = v.dot(d);
  const double denom = 1 - vd * vd;
  if (denom < 1e-12) return true;
  const double depth = (anchor.dot(d) - anchor.dot(v) * vd) / denom;
  return depth > 0;
}

}  // namespace internal

inline double SquaredReprojectionError(const PoseData& data, const CameraPoses& poses, size_t i,
                                       double cheirality_below) {
  constexpr double kInf = std::numeric_limits<double>::infinity();
  const int c = data.camera[i];
  const Eigen::Matrix3d& r = poses.rotation[c];
  const Eigen::Vector3d& t = poses.translation[c];
  const Eigen::Vector2d& x = data.normalized[i];
  const double f = data.focal[i];
  if (data.has_lines()) {
    const PluckerLine& l = data.lines[i];
    const Eigen::Vector3d w = poses.scaled_rotation[c] * l.w + poses.moment_from_v[c] * l.v;
    const double n2 = w.x() * w.x() + w.y() * w.y();
    if (!(n2 > 0)) return kInf;
    const double e = w.x() * x.x() + w.y() * x.y() + w.z();
    const double e2 = f * f * e * e / n2;
    // Cheirality only matters for residuals that could count as inliers.
    if (e2 < cheirality_below) {
      const Eigen::Vector3d v = r * l.v;
      if (!internal::LineInFront(v.cross(w), v, data.bearings[i])) return kInf;
    }
    return e2;
  }
  const Eigen::Vector3d p = poses.scale * (r * data.points[i]) + t;
  if (!(p.z() > 0)) return kInf;
  return f * f * (p.head<2>() / p.z() - x).squaredNorm();
}

}  // namespace linecloud
