// Aggregating localization results against ground truth: one tally for the
// demo's table and for `bench localize`.
#pragma once

#include <string>
#include <string_view>
#include <vector>

#include "linecloud/geometry/rigid3.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

struct LocalizationSummary {
  int queries = 0;
  int localized = 0;  // refined pose within the thresholds
  // Poses the success criteria accept (`confident` in Add) that are not within them.
  int confident_wrong = 0;
  double median_rotation_deg[2] = {0, 0};  // initial, refined
  double median_position[2] = {0, 0};      // in the unit passed to Add
  double iterations = 0;                   // means per query from here on
  double inlier_ratio = 0;
  double solutions = 0;
  double solver_us = 0;
  double ransac_ms = 0;
  double refine_ms = 0;
  double refine_iterations = 0;
  double total_ms = 0;         // RANSAC + refinement
  double median_total_ms = 0;  // median over the queries
  // Where RANSAC's time goes (means): minimal solvers, scoring, local
  // optimisation; the rest of ransac_ms is sampling and bookkeeping.
  double solver_ms = 0, scoring_ms = 0, lo_ms = 0;
  double reprojection_px[2] = {0, 0};  // initial, refined
  std::vector<std::string> failures;   // "name: reason" of each query without a pose
};

class LocalizationTally {
 public:
  // A query counts as localized when its refined pose is within
  // max_rotation_deg and max_position (in the unit of Add).
  LocalizationTally(double max_rotation_deg, double max_position);

  // Position errors are divided by `position_unit` (1: world units; the
  // scene size: relative). A failed query counts as 180° and 1e9 off.
  void Add(const LocalizeResult& result, const Sim3d& truth, double position_unit = 1.0,
           std::string_view name = "", bool confident = false);

  // Medians and means over the queries added so far.
  LocalizationSummary Summary() const;

 private:
  double max_rotation_deg_, max_position_;
  LocalizationSummary sums_;
  std::vector<double> rotation_[2], position_[2];
  std::vector<double> total_ms_;
};

}  // namespace linecloud
