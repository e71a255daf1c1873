#include "linecloud/benchmarks/localization_summary.h"

#include <algorithm>
#include <numbers>

#include "linecloud/util/statistics.h"
#include "linecloud/synthetic/localization_instances.h"

namespace linecloud {

LocalizationTally::LocalizationTally(double max_rotation_deg, double max_position)
    : max_rotation_deg_(max_rotation_deg), max_position_(max_position) {}

void LocalizationTally::Add(const LocalizeResult& r, const Sim3d& truth, double position_unit,
                            std::string_view name, bool confident) {
  constexpr double kDeg = 180.0 / std::numbers::pi;
  LocalizationSummary& s = sums_;
  ++s.queries;
  if (!r.success) s.failures.push_back(std::string(name) + ": " + r.failure);
  s.iterations += r.stats.iterations;
  s.inlier_ratio += r.stats.inlier_ratio;
  s.solutions += r.stats.mean_solutions;
  s.solver_us += r.stats.solver_us;
  s.ransac_ms += r.stats.ransac_ms;
  s.solver_ms += r.stats.solver_ms;
  s.scoring_ms += r.stats.scoring_ms;
  s.lo_ms += r.stats.lo_ms;
  total_ms_.push_back(r.stats.ransac_ms + r.refine_ms);
  s.refine_ms += r.refine_ms;
  s.refine_iterations += r.refine_iterations;
  s.reprojection_px[0] += r.reprojection_initial_px;
  s.reprojection_px[1] += r.reprojection_refined_px;
  const Sim3d* estimates[2] = {&r.initial, &r.query_from_world};
  for (int k = 0; k < 2; ++k) {
    if (r.success) {
      const LocalizationError e = CompareLocalization(*estimates[k], truth);
      rotation_[k].push_back(e.rotation_rad * kDeg);
      position_[k].push_back(e.position / position_unit);
    } else {
      rotation_[k].push_back(180);
      position_[k].push_back(1e9);
    }
  }
  const bool within =
      rotation_[1].back() < max_rotation_deg_ && position_[1].back() < max_position_;
  s.localized += within;
  if (confident && r.has_pose && !within) {
    const LocalizationError e = CompareLocalization(r.query_from_world, truth);
    s.confident_wrong += e.rotation_rad * 180.0 / std::numbers::pi >= max_rotation_deg_ ||
                         e.position / position_unit >= max_position_;
  }
}

LocalizationSummary LocalizationTally::Summary() const {
  LocalizationSummary s = sums_;
  const double n = std::max(1, s.queries);
  for (double* v : {&s.iterations, &s.inlier_ratio, &s.solutions, &s.solver_us, &s.ransac_ms,
                    &s.solver_ms, &s.scoring_ms, &s.lo_ms, &s.refine_ms, &s.refine_iterations,
                    &s.reprojection_px[0], &s.reprojection_px[1]}) {
    *v /= n;
  }
  s.total_ms = s.ransac_ms + s.refine_ms;
  s.median_total_ms = Median(total_ms_);
  for (int k = 0; k < 2; ++k) {
    s.median_rotation_deg[k] = Median(rotation_[k]);
    s.median_position[k] = Median(position_[k]);
  }
  return s;
}

}  // namespace linecloud
