// `eval run`'s report as types: what report.json holds, written by ToJson and read back by
// EvalReportFromJson (errors name the file and field). The evaluation computes one
// (eval_run.cc), the Markdown (eval_report_markdown.cc) and the figures (eval_figures.cc) are
// made from it alone, and `eval privacy` and the tests read its fields by name, not by string key.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

// An error before and after the refinement.
struct InitialRefined {
  double initial = 0;
  double refined = 0;
};

// Mean reprojection errors (px) over the inliers; for line methods, point_* are the
// point-to-point errors against the secret points.
struct ReprojectionErrors {
  double initial = 0, refined = 0, point_initial = 0, point_refined = 0;
};

// One query of the paper's protocol (a photo, or a group as a rig).
struct EvalQueryResult {
  std::string group, query;
  int correspondences = 0;
  bool success = false;
  InitialRefined rotation_deg{180, 180};
  InitialRefined translation{1e9, 1e9};  // the work's units
  int iterations = 0;
  double inlier_ratio = 0, mean_solutions = 0, solver_us = 0, ransac_ms = 0, refine_ms = 0;
  ReprojectionErrors reprojection_px;
  // With a pose: the observation noise σ̂ at the ground truth (px) and the Cramér–Rao bound of
  // the refined rotation with it (°; +∞ when the inliers do not fix the pose, null in JSON).
  std::optional<double> noise_px, rotation_bound_deg;
  std::string error;  // why there is no pose
};

// One method over its queries (Table 2's row) and the queries themselves.
struct EvalMethodReport {
  int queries = 0;
  int localized = 0;  // within 1° and 0.1 units
  double median_rotation_deg = 0, median_translation = 0;
  double median_rotation_deg_initial = 0, median_translation_initial = 0;
  std::map<std::string, double> recall;  // "1deg_0.1": share within 1° and 0.1 units
  double mean_iterations = 0, inlier_ratio = 0, mean_solutions = 0;
  double solver_us = 0, ransac_ms = 0, refine_ms = 0;  // means per query
  ReprojectionErrors reprojection_px;                  // means over the successes
  // Cramér–Rao check of the refined rotation (medians over the successes; NaN without one,
  // +∞ for a bound the inliers do not fix; null in JSON for both).
  double median_noise_px = 0;
  double median_rotation_bound_deg = 0;
  std::optional<double> rms_rotation_error_over_bound;
  std::vector<EvalQueryResult> per_query;
};

// The deployable protocol (direct_matching.h): one method on one query, photo or rig.
struct DirectMatchingAttempt {
  double rotation_deg = 180, translation = 1e9;  // 180 / 1e9: no pose
  bool attempted = false;  // enough matches for the method's sample (else only failure)
  bool success = false;
  double ransac_ms = 0;
  int iterations = 0, uniform_iterations = 0;
  int inliers = 0;
  std::vector<int> camera_inliers;  // a rig's inliers per camera
  std::string stop_reason;
  std::optional<double> sigma_px;
  // The reported 1-σ uncertainty of the pose (LocalizeResult::uncertainty:
  // rotation in degrees, centre in work units; null when undetermined).
  std::optional<double> sigma_rotation_deg, sigma_position;
  std::string failure;
};

struct DirectMatchingPhoto {
  std::string group, image;
  int features = 0, matches = 0;
  double extract_ms = 0, match_ms = 0;
  std::map<std::string, DirectMatchingAttempt> methods;  // by method name
};

struct DirectMatchingRig {
  std::string group;
  std::vector<std::string> images;
  int matches = 0;
  double rig_error_rotation_deg = 0, rig_error_translation = 0;  // the rig's own, worst camera
  std::map<std::string, DirectMatchingAttempt> methods;
};

struct DirectMatchingStageTimes {
  double extract = 0, match = 0, ransac = 0, refine = 0;
};

struct DirectMatchingSummary {
  int queries = 0, localized = 0;
  double median_rotation_deg = 0, median_translation = 0;
  DirectMatchingStageTimes mean_ms;
  double mean_solver_ms = 0, mean_scoring_ms = 0, mean_local_optimization_ms = 0;
  double mean_iterations = 0;
};

struct DirectMatchingReport {
  double max_rotation_deg = 0, max_translation = 0;  // "localized" thresholds
  std::string features;                              // the extractor
  std::map<std::string, DirectMatchingSummary> methods;
  std::vector<DirectMatchingPhoto> per_query;
  std::vector<DirectMatchingRig> per_rig;
};

// A sweep (Fig. 7: share of the map dropped; Fig. 8: synthetic pixel noise): per method, the
// median refined errors at each level.
struct EvalSweep {
  std::vector<double> levels;
  std::map<std::string, std::vector<double>> median_rotation_deg;
  // Density: in the work's units; noise: relative to the synthetic scene's extent.
  std::map<std::string, std::vector<double>> median_translation;
  int queries_per_level = 0;  // noise only (synthetic queries per method and level)
};

struct EvalReport {
  std::string dataset, units;
  double threshold_px = 0, sparsify = 0, noise_px = 0;
  std::string lifting;  // MapLifting::Name()
  uint64_t seed = 0;
  std::string gravity_source;
  // prepared.json's account of the reconstruction (COLMAP's, and against the ground truth).
  nlohmann::json reconstruction = nlohmann::json::object();
  std::map<std::string, EvalMethodReport> methods;  // by method name
  std::optional<DirectMatchingReport> direct_matching;
  std::optional<EvalSweep> density, noise;

  // The ground-truth alignment of the reconstruction, when prepared.json has one.
  struct GroundTruth {
    int aligned_on = 0;
    double max_rotation_deg = 0, max_position_m = 0;
  };
  std::optional<GroundTruth> ground_truth() const;
};

nlohmann::json ToJson(const EvalReport& report);
nlohmann::json ToJson(const DirectMatchingReport& report);
// `where` names the source in errors ("out/report.json").
EvalReport EvalReportFromJson(const nlohmann::json& j, const std::string& where);
DirectMatchingReport DirectMatchingReportFromJson(const nlohmann::json& j,
                                                  const std::string& where);
// Reads and checks a report.json.
EvalReport ReadEvalReport(const std::string& path);

// report.md's text (eval_report_markdown.cc).
std::string EvalReportMarkdown(const EvalReport& report);
// The PNG figures into `out_dir` (eval_figures.cc): cumulative errors (Fig. 5), and the density
// and noise sweeps (Figs. 7, 8) when the report has them.
void WriteEvalFigures(const EvalReport& report, const std::string& out_dir);

// A method's entry, or null.
template <typename Value>
const Value* FindIn(const std::map<std::string, Value>& by_method, std::string_view name) {
  const auto it = by_method.find(std::string(name));
  return it == by_method.end() ? nullptr : &it->second;
}

}  // namespace linecloud
