// Levenberg–Marquardt refinement of a query pose on the reprojection error
// (eq. 2 for points, eq. 6 for lines; Speciale et al., CVPR 2019) with a
// Cauchy loss, for single images and rigs, SE3 and Sim3.
#pragma once

#include <span>

#include "linecloud/estimation/pose_data.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

struct RefineOptions {
  int max_iterations = 30;
  double loss_scale = 1.0;           // Cauchy loss scale, px
  double function_tolerance = 1e-5;  // stop when the cost drops by less (relative)
  double step_tolerance = 1e-12;     // stop when the update is smaller
  bool similarity = false;           // also refine the scale (Sim3)

  void Check() const;
};

struct RefineSummary {
  int iterations = 0;
  double initial_cost = 0;  // Σ Cauchy loss over the residuals, px²
  double final_cost = 0;
};

// Refines query_from_world on the correspondences `indices` of `data`.
RefineSummary RefinePose(const PoseData& data, std::span<const int> indices,
                         const RefineOptions& options, Sim3d* query_from_world);

// Cramér–Rao bound of the rotation on these correspondences. With independent
// Gaussian noise of std. dev. sigma_px on every observation (both image axes),
// the rotation error ω of any unbiased estimate of query_from_world (the left
// perturbation of ReprojectionResidual, radians) has covariance
//     Cov(ω) ⪰ σ² [F⁻¹]_ωω,   F = Σᵢ Jᵢᵀ Jᵢ over `indices`,
// Jᵢ the residual Jacobian at the true pose `query_from_world`: two rows for a
// point (eq. 2), one for a line (eq. 6 — a line measures only the
// observation's offset across its projection). Translation (and with
// `similarity` the scale) are nuisance parameters, hence the inverse before
// taking the block. Returns √trace σ²[F⁻¹]_ωω: the smallest RMS rotation error
// (radians) any estimator can reach; +∞ when the rotation is not determined.
// A gauge freedom the rotation does not depend on (the scale of a Sim3 pose
// seen by one camera) is left out: F⁺ instead of F⁻¹ (the same block for any
// gauge).
double RotationErrorBound(const PoseData& data, std::span<const int> indices,
                          const Sim3d& query_from_world, double sigma_px, bool similarity);

// How well the data determine an estimated pose: the covariance σ̂² F⁻¹ of
// the Gauss–Newton linearisation at the estimate (F as in RotationErrorBound,
// at the estimate instead of the truth), with the noise σ̂ estimated from the
// residuals themselves, σ̂² = Σ r² / (rows − parameters). A wrong calibration
// raises σ̂, a weak geometry (few, clustered or nearly degenerate
// correspondences) raises F⁻¹; either shows here. Rotation and centre are
// reported when the data determine them even if the whole pose is not: one
// camera fixes both but not a Sim3 pose's scale (F⁺, as in RotationErrorBound);
// +∞ for what is undetermined.
struct PoseUncertainty {
  double sigma_px = 0;  // estimated observation noise, px
  // RMS (√trace) 1-σ uncertainty of the rotation, degrees, and of the query's
  // centre (camera or rig origin; camera 0's centre when the data determine
  // the cameras but not the rig origin) in world units; +∞ when undetermined.
  double rotation_deg = 0;
  double position = 0;
};
//
// local_sigma > 0 (the local points' noise, FitScaleToLocalPoints): when the
// reprojections leave a direction free (the scale seen by one camera), the
// local points' 3D residuals (LocalPointResidual) join them, each kind
// whitened by its own noise, so the rig origin is reported.
PoseUncertainty EstimatePoseUncertainty(const PoseData& data, std::span<const int> indices,
                                        const Sim3d& query_from_world, bool similarity,
                                        double local_sigma = 0);

// Applies the left perturbation of ReprojectionResidual: (ω, δt, δσ).
Sim3d PerturbPose(const Sim3d& pose, const Eigen::Matrix<double, 7, 1>& delta);

}  // namespace linecloud
