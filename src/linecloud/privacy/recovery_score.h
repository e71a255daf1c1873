// How close an attacker's recovered points come to the secret points: what
// `linecloud audit` reports to a map owner.
#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

namespace linecloud {

// The diagonal of the box spanned per axis by the 0.5 % and 99.5 %
// percentiles of the points: the scene's size without SfM's stray points.
double SceneDiagonal(std::span<const Eigen::Vector3d> points);

struct RecoveryScore {
  size_t points = 0;
  double diagonal = 0;      // model units
  double metric_scale = 0;  // metres per model unit; 0: not metric
  double median_error = 0;  // model units
  // Share of points recovered within each threshold: percent of the diagonal,
  // and metres when metric.
  std::vector<std::pair<double, double>> within_diagonal_percent;
  std::vector<std::pair<double, double>> within_metres;
  std::vector<double> errors;  // per point, model units
};

// Thresholds: 0.5 / 1 / 2 % of the diagonal; 1 / 5 / 10 / 25 cm when metric.
RecoveryScore ScoreRecovery(std::span<const Eigen::Vector3d> recovered,
                            std::span<const Eigen::Vector3d> secret, double metric_scale);

// Share within `percent` % of the diagonal (one of the thresholds above).
double ShareWithinDiagonal(const RecoveryScore& score, double percent);

}  // namespace linecloud
