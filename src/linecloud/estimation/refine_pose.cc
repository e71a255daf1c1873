#include "linecloud/estimation/refine_pose.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

double CauchyLoss(double squared, double c2) { return c2 * std::log1p(squared / c2); }

double Cost(const PoseData& data, std::span<const int> indices, const Sim3d& pose,
            double c2) {
  const CameraPoses poses(data, pose);
  double cost = 0;
  for (const int i : indices) {
    // Behind the camera (+∞): the value the loss takes at 1000 px.
    cost += CauchyLoss(std::min(1e6, SquaredReprojectionError(data, poses, i)), c2);
  }
  return cost;
}

}  // namespace

void RefineOptions::Check() const {
  if (max_iterations < 0) Fail("refinement: max_iterations must be >= 0");
  if (!(loss_scale > 0) || !std::isfinite(loss_scale)) {
    Fail("refinement: loss_scale must be a positive number, got {}", loss_scale);
  }
}

Sim3d PerturbPose(const Sim3d& pose, const Eigen::Matrix<double, 7, 1>& delta) {
  const Eigen::Vector3d omega = delta.head<3>();
  const double angle = omega.norm();
  const Eigen::Quaterniond dq =
      angle > 0 ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))
                : Eigen::Quaterniond::Identity();
  return Sim3d(pose.scale * std::exp(delta[6]), (dq * pose.rotation).normalized(),
               pose.translation + delta.segment<3>(3));
}

RefineSummary RefinePose(const PoseData& data, std::span<const int> indices,
                         const RefineOptions& options, Sim3d* pose) {
  options.Check();
  const double c2 = options.loss_scale * options.loss_scale;
  const int dim = options.similarity ? 7 : 6;
  RefineSummary summary;
  double cost = Cost(data, indices, *pose, c2);
  summary.initial_cost = summary.final_cost = cost;
  double lambda = 1e-3;
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 7> j;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    summary.iterations = iteration + 1;
    // Gauss–Newton system with IRLS weights ρ'(r²) of the Cauchy loss.
    Eigen::Matrix<double, 7, 7> h = Eigen::Matrix<double, 7, 7>::Zero();
    Eigen::Matrix<double, 7, 1> g = Eigen::Matrix<double, 7, 1>::Zero();
    const PoseLinearization linearization(data, *pose);
    for (const int i : indices) {
      const int n = ReprojectionResidual(data, linearization, static_cast<size_t>(i), &r, &j);
      if (n == 0) continue;
      // Lines: the second row of r and j is zero.
      const double weight = 1.0 / (1.0 + r.squaredNorm() / c2);
      h.noalias() += weight * j.transpose() * j;
      g.noalias() += weight * j.transpose() * r;
    }
    bool improved = false;
    while (!improved && lambda < 1e12) {
      Eigen::MatrixXd damped = h.topLeftCorner(dim, dim);
      // Marquardt damping; the floor keeps gauge directions (the scale of a
      // single camera at the rig origin) from blowing up.
      const double floor = 1e-12 * std::max(1.0, damped.diagonal().maxCoeff());
      for (int k = 0; k < dim; ++k) damped(k, k) += lambda * (damped(k, k) + floor);
      Eigen::Matrix<double, 7, 1> delta = Eigen::Matrix<double, 7, 1>::Zero();
      delta.head(dim) = -damped.ldlt().solve(g.head(dim));
      if (!delta.allFinite()) break;
      const Sim3d candidate = PerturbPose(*pose, delta);
      const double candidate_cost = Cost(data, indices, candidate, c2);
      if (candidate_cost < cost) {
        const double decrease = cost - candidate_cost;
        *pose = candidate;
        const bool converged = decrease < options.function_tolerance * cost ||
                               delta.norm() < options.step_tolerance;
        cost = candidate_cost;
        lambda = std::max(1e-9, lambda / 10);
        improved = true;
        if (converged) {
          summary.final_cost = cost;
          return summary;
        }
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  summary.final_cost = cost;
  return summary;
}

}  // namespace linecloud
