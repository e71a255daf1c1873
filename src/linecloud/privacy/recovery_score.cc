#include "linecloud/privacy/recovery_score.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

double SceneDiagonal(std::span<const Eigen::Vector3d> points) {
  if (points.empty()) return 0;
  return RobustBox(points, 0.005, 0.0).diagonal().norm();
}

RecoveryScore ScoreRecovery(std::span<const Eigen::Vector3d> recovered,
                            std::span<const Eigen::Vector3d> secret, double metric_scale) {
  if (recovered.size() != secret.size()) {
    Fail("audit: {} recovered points for {} secret points", recovered.size(), secret.size());
  }
  if (!(metric_scale >= 0) || !std::isfinite(metric_scale)) {
    Fail("--metric-scale: {} is not a finite non-negative number", metric_scale);
  }
  RecoveryScore s;
  s.points = secret.size();
  s.diagonal = SceneDiagonal(secret);
  s.metric_scale = metric_scale;
  s.errors.resize(s.points);
  for (size_t i = 0; i < s.points; ++i) s.errors[i] = (recovered[i] - secret[i]).norm();
  s.median_error = Quantile(s.errors, 0.5);
  auto share_within = [&](double threshold) {
    if (s.points == 0) return 0.0;
    return static_cast<double>(std::count_if(s.errors.begin(), s.errors.end(),
                                             [&](double e) { return e <= threshold; })) /
           s.points;
  };
  for (const double p : {0.5, 1.0, 2.0}) {
    s.within_diagonal_percent.push_back({p, share_within(p / 100 * s.diagonal)});
  }
  if (metric_scale > 0) {
    for (const double m : {0.01, 0.05, 0.10, 0.25}) {
      s.within_metres.push_back({m, share_within(m / metric_scale)});
    }
  }
  return s;
}

double ShareWithinDiagonal(const RecoveryScore& score, double percent) {
  for (const auto& [p, share] : score.within_diagonal_percent) {
    if (p == percent) return share;
  }
  Fail("audit: no share within {} % of the diagonal", percent);
}

}  // namespace linecloud
