// The scale of a +l pose seen by one camera, from the local points.
//
// A +l query carries, with each observation, the point X̃ᵢ its device
// reconstructed in the query (rig) frame, at an unknown scale. With one camera
// (or every inlier in one camera) the reprojections fix that camera's
// cam_from_world but leave the scale of query_from_world free: changing it
// moves the rig origin about the camera along a gauge the LM cannot see. The
// scale then comes from the local points' 3D residuals. Holding the camera's
// world pose (R, centre C) fixed,
//     query_from_world(x) = s R (x − C) + c,   c = the camera centre in the rig frame,
// and each residual is linear in s:
//     point map:  rᵢ = X̃ᵢ − query_from_world(Xᵢ)          = bᵢ − s dᵢ,
//                 bᵢ = X̃ᵢ − c,  dᵢ = R (Xᵢ − C);
//     line map:   rᵢ = (X̃ᵢ − query_from_world(Aᵢ)) × R vᵢ = bᵢ − s dᵢ,
//                 bᵢ = (X̃ᵢ − c) × R vᵢ,  dᵢ = R (Aᵢ − C) × R vᵢ,
// Aᵢ a point of map line i (its anchor) and vᵢ its unit direction: |rᵢ| is the
// distance of X̃ᵢ from the line carried into the rig frame. Least squares:
//     s = Σ bᵢ·dᵢ / Σ |dᵢ|²,   σ̂² = Σ |rᵢ|² / (k − 1),   se(log s) = σ̂ / (s √Σ|dᵢ|²),
// k the residual's degrees of freedom (3 per point, 2 per line).
#pragma once

#include <optional>
#include <span>

#include <Eigen/Core>

#include "linecloud/estimation/pose_data.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// The 3D residual of correspondence i's local point at query_from_world, in
// the rig frame's units (rᵢ above). Precondition: data has points_local.
Eigen::Vector3d LocalPointResidual(const PoseData& data, int i, const Sim3d& query_from_world);

struct LocalScaleFit {
  double scale_before = 0;  // the scale the pose had
  double sigma_local = 0;   // σ̂: the local points' noise, rig units
  double log_scale_se = 0;  // standard error of log s
};

// Whether every correspondence in `indices` is seen by one camera: then the
// reprojections leave the scale of a similarity pose free.
bool SeenByOneCamera(const PoseData& data, std::span<const int> indices);

// Refits the scale of *query_from_world as above on `indices`, the camera's
// world pose kept. nullopt (pose untouched) when the data have no local
// points, fewer than two correspondences or no scale fits (Σ|dᵢ|² = 0 or
// s ≤ 0).
std::optional<LocalScaleFit> FitScaleToLocalPoints(const PoseData& data,
                                                   std::span<const int> indices,
                                                   Sim3d* query_from_world);

}  // namespace linecloud
