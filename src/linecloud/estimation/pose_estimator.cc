#include "linecloud/estimation/pose_estimator.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace linecloud {

PoseEstimator::PoseEstimator(const MethodInfo& method, const PoseData& data,
                             const RefineOptions& local_refinement)
    : method_(method), data_(data), local_refinement_(local_refinement) {
  data.Check("PoseEstimator");
  if (method.lines != data.has_lines() && data.size() > 0) {
    Fail("PoseEstimator: method {} needs {}, the pose data has {}", method.name,
         method.lines ? "lines" : "points", data.has_lines() ? "lines" : "points");
  }
  if (method.local_points && data.points_local.size() != data.size()) {
    Fail("PoseEstimator: method {} needs a local point per correspondence", method.name);
  }
  local_refinement_.similarity = method.similarity();
  if (method.multi && !method.local_points) sample_.cam_from_rig = data.cam_from_rig;
  if (!method.multi && !data.cam_from_rig.empty()) {
    camera_to_query_ = data.cam_from_rig[0].rotation.inverse().toRotationMatrix();
  }
}

int PoseEstimator::generate_models(std::span<const int> sample, std::vector<Sim3d>* out) {
  MinimalSample& s = sample_;
  s.bearings.clear();
  s.camera_index.clear();
  s.points_local.clear();
  s.points.clear();
  s.lines.clear();
  for (const int i : sample) {
    if (method_.local_points) {
      s.points_local.push_back(data_.points_local[i]);
    } else {
      if (method_.multi) {
        s.bearings.push_back(data_.bearings[i]);
        s.camera_index.push_back(data_.camera[i]);
      } else {
        // One camera at the origin of the query frame, possibly rotated
        // (gravity pre-alignment): bearings in the query frame.
        s.bearings.push_back(camera_to_query_ * data_.bearings[i]);
      }
    }
    if (method_.lines) {
      s.lines.push_back(data_.lines[i]);
    } else {
      s.points.push_back(data_.points[i]);
    }
  }
  return SolveMinimal(method_, s, out);
}

double PoseEstimator::score_model(const Sim3d& model, double threshold, double bound,
                                  int* num_inliers) const {
  const CameraPoses poses(data_, model);
  const double t2 = threshold * threshold;
  const size_t n = data_.size();
  // Sequential probability ratio test (Matas & Chum, "Randomized RANSAC with
  // sequential probability ratio test", ICCV 2005) once a best model exists:
  // its MSAC score bounds the inlier ratio from below, ε ≥ 1 − bound / (n t²);
  // a wrong model agrees with a correspondence with probability δ. The
  // likelihood ratio λ of "wrong" against "good" grows by (1 − δ)/(1 − ε) per
  // outlier and shrinks by δ/ε per inlier; the model is dropped once λ > A.
  constexpr double kDelta = 0.05;
  constexpr double kDecision = 1000;
  const bool sprt = std::isfinite(bound);
  double lambda = 1, outlier_factor = 1, inlier_factor = 1;
  if (sprt) {
    const double epsilon =
        std::clamp(1.0 - bound / (static_cast<double>(n) * t2), 2 * kDelta, 0.99);
    outlier_factor = (1 - kDelta) / (1 - epsilon);
    inlier_factor = kDelta / epsilon;
  }
  double score = 0;
  int inliers = 0;
  for (size_t i = 0; i < n; ++i) {
    const double e2 = SquaredReprojectionError(data_, poses, i, t2);
    if (e2 < t2) {
      score += e2;
      ++inliers;
      lambda *= inlier_factor;
    } else {
      score += t2;
      if (score >= bound) break;  // cannot beat the best model any more
      lambda *= outlier_factor;
      if (sprt && lambda > kDecision) {
        score = std::numeric_limits<double>::infinity();  // rejected as wrong
        break;
      }
    }
  }
  *num_inliers = inliers;
  return score;
}

void PoseEstimator::inliers(const Sim3d& model, double threshold, std::vector<char>* mask) const {
  const CameraPoses poses(data_, model);
  mask->assign(data_.size(), 0);
  const double t2 = threshold * threshold;
  for (size_t i = 0; i < data_.size(); ++i) {
    (*mask)[i] = SquaredReprojectionError(data_, poses, i, t2) < t2;
  }
}

void PoseEstimator::refine_model(Sim3d* model, double threshold) {
  // LO+ (Lebeda, Matas, Chum, "Fixing the locally optimized RANSAC", BMVC
  // 2012): least squares on the inliers at a wider threshold first, then
  // narrowing to the threshold, so that a model from a nearly right sample
  // (2-3° off: its inliers at the threshold a subset of the true ones) is
  // drawn to the true pose instead of staying where it was fitted.
  for (const double widen : {3.0, 1.5, 1.0}) RefineOnInliers(model, widen * threshold);
}

void PoseEstimator::RefineOnInliers(Sim3d* model, double threshold) {
  std::vector<char> mask;
  inliers(*model, threshold, &mask);
  InlierIndices(mask, &inlier_indices_);
  if (inlier_indices_.size() < static_cast<size_t>(method_.sample_size)) return;
  // A few LM steps on thousands of inliers cost more than the minimal solver;
  // an evenly spaced subset moves the model as far (the final refinement
  // uses every inlier). Lebeda, Matas, Chum, "Fixing the locally optimized
  // RANSAC", BMVC 2012, bound the inner least squares the same way.
  const size_t count = inlier_indices_.size();
  if (count > kMaxLocalOptimizationData) {
    for (size_t j = 0; j < kMaxLocalOptimizationData; ++j) {
      inlier_indices_[j] = inlier_indices_[j * count / kMaxLocalOptimizationData];
    }
    inlier_indices_.resize(kMaxLocalOptimizationData);
  }
  RefinePose(data_, inlier_indices_, local_refinement_, model);
}

}  // namespace linecloud
