#include "linecloud/estimation/refine_pose.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <limits>
#include <numbers>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>

#include "linecloud/estimation/local_scale.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

double CauchyLoss(double squared, double c2) { return c2 * std::log1p(squared / c2); }

// The value the loss takes for a correspondence behind its camera: its loss
// at 1000 px.
constexpr double kBehindSquared = 1e6;

// Σ ρ(r²) over the correspondences and the Gauss–Newton system of the
// IRLS-weighted residuals (weights ρ'(r²) of the Cauchy loss), in one pass:
// the LM loop evaluates each candidate once and, when it is accepted, already
// has the system for the next step. Only the upper triangle of h is filled.
struct Linearization {
  double cost = 0;
  Eigen::Matrix<double, 7, 7> h;
  Eigen::Matrix<double, 7, 1> g;
};

void Linearize(const PoseData& data, std::span<const int> indices, const Sim3d& pose, double c2,
               Linearization* out) {
  out->cost = 0;
  out->h.setZero();
  out->g.setZero();
  const PoseLinearization linearization(data, pose);
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 7> j;
  for (const int i : indices) {
    const int n = ReprojectionResidual(data, linearization, static_cast<size_t>(i), &r, &j);
    if (n == 0) {
      out->cost += CauchyLoss(kBehindSquared, c2);
      continue;
    }
    const double squared = r.squaredNorm();  // lines: the second entry is 0
    out->cost += CauchyLoss(std::min(kBehindSquared, squared), c2);
    const double weight = 1.0 / (1.0 + squared / c2);
    for (int row = 0; row < n; ++row) {
      const Eigen::Matrix<double, 1, 7> jr = j.row(row);
      out->h.template selfadjointView<Eigen::Upper>().rankUpdate(jr.transpose(), weight);
      out->g.noalias() += (weight * r[row]) * jr.transpose();
    }
  }
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
  const Eigen::Quaterniond dq = angle > 0
                                    ? Eigen::Quaterniond(Eigen::AngleAxisd(angle, omega / angle))
                                    : Eigen::Quaterniond::Identity();
  return Sim3d(pose.scale * std::exp(delta[6]), (dq * pose.rotation).normalized(),
               pose.translation + delta.segment<3>(3));
}

RefineSummary RefinePose(const PoseData& data, std::span<const int> indices,
                         const RefineOptions& options, Sim3d* pose) {
  options.Check();
  if (pose == nullptr) Fail("RefinePose: no pose given (null pointer)");
  data.Check("RefinePose");
  CheckIndices(data, indices, "RefinePose");
  const double c2 = options.loss_scale * options.loss_scale;
  const int dim = options.similarity ? 7 : 6;
  RefineSummary summary;
  Linearization current, candidate;
  Linearize(data, indices, *pose, c2, &current);
  summary.initial_cost = summary.final_cost = current.cost;
  double lambda = 1e-3;
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    summary.iterations = iteration + 1;
    bool improved = false;
    while (!improved && lambda < 1e12) {
      // Marquardt damping on the active block (the scale column stays out
      // for SE3); the floor keeps gauge directions (the scale of a single
      // camera at the rig origin) from blowing up.
      Eigen::Matrix<double, 7, 7> damped = current.h;
      damped.triangularView<Eigen::StrictlyLower>() = damped.transpose();
      double largest = 1.0;
      for (int k = 0; k < dim; ++k) largest = std::max(largest, damped(k, k));
      const double floor = 1e-12 * largest;
      for (int k = 0; k < dim; ++k) damped(k, k) += lambda * (damped(k, k) + floor);
      Eigen::Matrix<double, 7, 1> delta = Eigen::Matrix<double, 7, 1>::Zero();
      if (dim == 7) {
        delta = -damped.ldlt().solve(current.g);
      } else {
        delta.head<6>() = -damped.topLeftCorner<6, 6>().ldlt().solve(current.g.head<6>());
      }
      if (!delta.allFinite()) break;
      const Sim3d moved = PerturbPose(*pose, delta);
      Linearize(data, indices, moved, c2, &candidate);
      if (candidate.cost < current.cost) {
        const double decrease = current.cost - candidate.cost;
        const bool converged = decrease < options.function_tolerance * current.cost ||
                               delta.norm() < options.step_tolerance;
        *pose = moved;
        std::swap(current, candidate);
        lambda = std::max(1e-9, lambda / 10);
        improved = true;
        if (converged) {
          summary.final_cost = current.cost;
          return summary;
        }
      } else {
        lambda *= 10;
      }
    }
    if (!improved) break;
  }
  summary.final_cost = current.cost;
  return summary;
}

namespace {

// What the correspondences say about a pose: the Gauss–Newton information
// F = Σᵢ JᵢᵀJᵢ of their residuals at `pose` on its first `dim` parameters,
// its pseudo-inverse F⁺ and null space N (the directions no residual sees,
// e.g. the scale of a Sim3 pose seen by one camera: (s, t) → (e^ε s, e^ε t)
// moves no projection), and the residuals' Σ r² and row count.
struct PoseInformation {
  Eigen::MatrixXd fisher;      // F
  Eigen::MatrixXd inverse;     // F⁺ (F⁻¹ when N is empty)
  Eigen::MatrixXd null_space;  // dim x k, orthonormal columns
  double sum_sq = 0;
  int rows = 0;
};

void Invert(PoseInformation* info);

PoseInformation InformationAt(const PoseData& data, std::span<const int> indices, const Sim3d& pose,
                              int dim) {
  const PoseLinearization linearization(data, pose);
  Eigen::Matrix<double, 7, 7> fisher = Eigen::Matrix<double, 7, 7>::Zero();
  struct Row {
    Eigen::Vector2d r;
    Eigen::Matrix<double, 2, 7> j;
    int n = 0;
  };
  std::vector<Row> rows(indices.size());
  std::vector<double> norms;
  for (size_t k = 0; k < indices.size(); ++k) {
    Row& row = rows[k];
    row.n =
        ReprojectionResidual(data, linearization, static_cast<size_t>(indices[k]), &row.r, &row.j);
    if (row.n > 0) norms.push_back(row.j.norm());
  }
  // A line passing within millimetres of the camera centre moves across the
  // image with the slightest motion: its Jacobian is 10⁶ times the others'
  // (EuRoC, 1 of 1 083 inliers) and alone would make every other direction
  // look undetermined. Its true information is bounded by the map's own 3D
  // noise, which this model of pixel noise leaves out: such rows (more than
  // 1 000 times the median Jacobian) are left out.
  double limit = std::numeric_limits<double>::infinity();
  if (!norms.empty()) {
    std::nth_element(norms.begin(), norms.begin() + norms.size() / 2, norms.end());
    limit = 1e3 * norms[norms.size() / 2];
  }
  PoseInformation info;
  for (const Row& row : rows) {
    if (row.n == 0 || !(row.j.norm() <= limit)) continue;
    for (int k = 0; k < row.n; ++k) fisher.noalias() += row.j.row(k).transpose() * row.j.row(k);
    info.sum_sq += row.r[0] * row.r[0] + (row.n == 2 ? row.r[1] * row.r[1] : 0.0);
    info.rows += row.n;
  }
  info.fisher = fisher.topLeftCorner(dim, dim);
  Invert(&info);
  return info;
}

// F⁺ and the null space of info->fisher.
void Invert(PoseInformation* info) {
  const int dim = static_cast<int>(info->fisher.rows());
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eigen(info->fisher);
  const Eigen::VectorXd& values = eigen.eigenvalues();  // ascending
  const double tolerance = 1e-12 * std::max(values[dim - 1], 0.0);
  int null_dim = 0;
  while (null_dim < dim && !(values[null_dim] > tolerance)) ++null_dim;
  info->null_space = eigen.eigenvectors().leftCols(null_dim);
  Eigen::VectorXd inverse_values = Eigen::VectorXd::Zero(dim);
  for (int k = null_dim; k < dim; ++k) inverse_values[k] = 1.0 / values[k];
  info->inverse =
      eigen.eigenvectors() * inverse_values.asDiagonal() * eigen.eigenvectors().transpose();
}

// Σᵢ JᵢᵀJᵢ of the local points' 3D residuals (LocalPointResidual) over the
// pose's perturbation, by central differences.
Eigen::MatrixXd LocalPointInformation(const PoseData& data, std::span<const int> indices,
                                      const Sim3d& pose, int dim) {
  Eigen::MatrixXd fisher = Eigen::MatrixXd::Zero(dim, dim);
  const double h = 1e-6 * std::max(1.0, pose.translation.norm());
  Eigen::Matrix<double, 3, Eigen::Dynamic> j(3, dim);
  for (const int i : indices) {
    for (int k = 0; k < dim; ++k) {
      Eigen::Matrix<double, 7, 1> d = Eigen::Matrix<double, 7, 1>::Zero();
      const double step = k < 3 || k == 6 ? 1e-7 : h;
      d[k] = step;
      const Eigen::Vector3d plus = LocalPointResidual(data, i, PerturbPose(pose, d));
      d[k] = -step;
      j.col(k) = (plus - LocalPointResidual(data, i, PerturbPose(pose, d))) / (2 * step);
    }
    fisher.noalias() += j.transpose() * j;
  }
  return fisher;
}

// Whether the quantity with Jacobian `jacobian` (rows) is determined by the
// data: it does not change along any direction of the null space. Then its
// covariance through F⁺ is the same whatever the gauge.
bool Determined(const Eigen::MatrixXd& jacobian, const PoseInformation& info) {
  if (info.null_space.cols() == 0) return true;
  if (info.null_space.cols() == info.null_space.rows()) return false;
  return (jacobian * info.null_space).norm() <= 1e-6 * std::max(1.0, jacobian.norm());
}

}  // namespace

PoseUncertainty EstimatePoseUncertainty(const PoseData& data, std::span<const int> indices,
                                        const Sim3d& query_from_world, bool similarity,
                                        double local_sigma) {
  data.Check("EstimatePoseUncertainty");
  CheckIndices(data, indices, "EstimatePoseUncertainty");
  const int dim = similarity ? 7 : 6;
  PoseInformation info = InformationAt(data, indices, query_from_world, dim);
  PoseUncertainty u;
  u.rotation_deg = u.position = std::numeric_limits<double>::infinity();
  const int free = dim - static_cast<int>(info.null_space.cols());
  if (info.rows <= free) return u;
  u.sigma_px = std::sqrt(info.sum_sq / (info.rows - free));
  if (local_sigma > 0 && !data.points_local.empty() && info.null_space.cols() > 0 &&
      u.sigma_px > 0) {
    // F/σ² + F₃/σ₃² = (F + (σ/σ₃)² F₃)/σ²: each kind of residual whitened by
    // its own noise. Only along the null space N: the estimate takes from the
    // local points what the reprojections leave free, nothing else.
    const double weight = (u.sigma_px / local_sigma) * (u.sigma_px / local_sigma);
    const Eigen::MatrixXd& n = info.null_space;
    info.fisher +=
        weight * n *
        (n.transpose() * LocalPointInformation(data, indices, query_from_world, dim) * n) *
        n.transpose();
    Invert(&info);
  }
  const Eigen::MatrixXd covariance = u.sigma_px * u.sigma_px * info.inverse;
  const Eigen::MatrixXd jr = Eigen::MatrixXd::Identity(3, dim);
  if (Determined(jr, info)) {
    u.rotation_deg = std::sqrt(covariance.topLeftCorner<3, 3>().trace()) * 180.0 / std::numbers::pi;
  }
  // The position: of the query frame's origin (a rig's), or, when only the
  // cameras are determined (one camera offset from the rig origin under an
  // unknown scale: the scale moves the origin about the camera), of camera 0's
  // centre. Jacobians by central differences of the perturbation.
  const auto centre_jacobian = [&](const Rigid3d* cam_from_rig) {
    const auto centre = [&](const Sim3d& pose) {
      const Sim3d world_from_query = pose.Inverse();
      return cam_from_rig
                 ? Eigen::Vector3d(world_from_query * (cam_from_rig->Inverse().translation))
                 : world_from_query.translation;
    };
    const double h = 1e-6 * std::max(1.0, centre(query_from_world).norm());
    Eigen::MatrixXd jc(3, dim);
    for (int k = 0; k < dim; ++k) {
      Eigen::Matrix<double, 7, 1> d = Eigen::Matrix<double, 7, 1>::Zero();
      const double step = k < 3 || k == 6 ? 1e-7 : h;
      d[k] = step;
      const Eigen::Vector3d plus = centre(PerturbPose(query_from_world, d));
      d[k] = -step;
      jc.col(k) = (plus - centre(PerturbPose(query_from_world, d))) / (2 * step);
    }
    return jc;
  };
  for (const Rigid3d* cam : {static_cast<const Rigid3d*>(nullptr), &data.cam_from_rig.at(0)}) {
    const Eigen::MatrixXd jc = centre_jacobian(cam);
    if (Determined(jc, info)) {
      u.position = std::sqrt((jc * covariance * jc.transpose()).trace());
      break;
    }
  }
  return u;
}

double RotationErrorBound(const PoseData& data, std::span<const int> indices,
                          const Sim3d& query_from_world, double sigma_px, bool similarity) {
  data.Check("RotationErrorBound");
  CheckIndices(data, indices, "RotationErrorBound");
  const int dim = similarity ? 7 : 6;
  const PoseInformation info = InformationAt(data, indices, query_from_world, dim);
  if (!Determined(Eigen::MatrixXd::Identity(3, dim), info)) {
    return std::numeric_limits<double>::infinity();
  }
  return sigma_px * std::sqrt(info.inverse.topLeftCorner<3, 3>().trace());
}

}  // namespace linecloud
