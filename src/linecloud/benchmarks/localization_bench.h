// `linecloud bench localize`: every method on the same seeded synthetic
// queries (RandomLocalizationInstance), single thread — accuracy of the
// initial and refined poses, RANSAC statistics and time per query. Each
// privacy-preserving method sees exactly the queries of its point-map
// counterpart (Speciale et al., CVPR 2019, Table 1 pairs).
#pragma once

#include <nlohmann/json.hpp>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "linecloud/benchmarks/localization_summary.h"
#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/localization_instances.h"

namespace linecloud {

struct LocalizationBenchOptions {
  int queries = 100;
  uint64_t seed = 1;
  LocalizationInstanceOptions instance;  // 500 correspondences, 70 % inliers, 1 px
  LocalizeOptions localize;
  double max_rotation_deg = 1.0;     // "localized" thresholds
  double max_position_rel = 0.01;    // of the scene size
  std::vector<std::string> methods;  // empty: all implemented

  void Check() const;
};

struct LocalizationBenchRow : LocalizationSummary {
  std::string method;       // median_position relative to the scene size
  std::string counterpart;  // the same problem with the other map kind
  // Cramér–Rao bound of the refined rotation (RotationErrorBound at the true
  // pose, on the query's true inliers, σ = the pixel noise), degrees, median
  // over the queries: for this method's map and for the counterpart's map of
  // the same queries. Their ratio is the least by which one map kind must
  // trail the other, whatever the estimator.
  double rotation_bound_deg = 0;
  double counterpart_rotation_bound_deg = 0;

  nlohmann::json ToJson() const;  // a row of `bench localize --json`
};

// The method with the same query data and model but the other map kind.
std::string CounterpartMethod(const MethodInfo& method);

std::vector<LocalizationBenchRow> RunLocalizationBench(
    const LocalizationBenchOptions& options,
    const std::function<void(const std::string&)>& progress);

// What `bench localize` prints: the rows under the options that made them
// (bench_tables.cc).
struct LocalizationBenchReport {
  LocalizationBenchOptions options;
  std::vector<LocalizationBenchRow> rows;
};

// {"seed", "inlier_ratio", "match_scores", "progressive_sampling", "rows"}.
nlohmann::json ToJson(const LocalizationBenchReport& report);
// The settings line, the table (with each row's ratio to its counterpart) and its legend.
std::string LocalizationBenchMarkdown(const LocalizationBenchReport& report);

}  // namespace linecloud
