// The RANSAC estimator shared by all 16 methods: minimal samples go to the
// method's minimal solver, models are scored by the reprojection error in
// pixels (eq. 2 for point maps, eq. 6 for line clouds) — also for the +λ
// methods, whose local points only drive the minimal solvers (see README:
// the same residual and threshold for every method keeps the comparison
// fair, and pixel noise does not grow with depth as local-point noise does) —
// and new best models are locally optimised by a few LM steps.
#pragma once

#include <span>
#include <vector>

#include "linecloud/estimation/pose_data.h"
#include "linecloud/estimation/ransac.h"
#include "linecloud/estimation/refine_pose.h"
#include "linecloud/solvers/minimal_problem.h"

namespace linecloud {

class PoseEstimator {
 public:
  // Local optimisation fits at most this many inliers (evenly spaced).
  static constexpr size_t kMaxLocalOptimizationData = 400;

  using Model = Sim3d;  // query_from_world

  // `data` must outlive the estimator.
  PoseEstimator(const MethodInfo& method, const PoseData& data,
                const RefineOptions& local_refinement);

  int num_data() const { return static_cast<int>(data_.size()); }
  int sample_size() const { return method_.sample_size; }
  int generate_models(std::span<const int> sample, std::vector<Sim3d>* out);
  double score_model(const Sim3d& model, double threshold, double bound, int* num_inliers) const;
  void refine_model(Sim3d* model, double threshold);
  void inliers(const Sim3d& model, double threshold, std::vector<char>* mask) const;

 private:
  // One LM refinement on the inliers of `model` at `threshold` (a subset of them when many).
  void RefineOnInliers(Sim3d* model, double threshold);
  const MethodInfo& method_;
  const PoseData& data_;
  RefineOptions local_refinement_;
  MinimalSample sample_;
  Eigen::Matrix3d camera_to_query_ = Eigen::Matrix3d::Identity();  // one-image methods
  std::vector<int> inlier_indices_;
};

}  // namespace linecloud
