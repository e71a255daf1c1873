#include "linecloud/benchmarks/localization_bench.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <fmt/format.h>

#include "linecloud/estimation/refine_pose.h"
#include "linecloud/util/statistics.h"
#include "linecloud/util/error.h"

namespace linecloud {
void LocalizationBenchOptions::Check() const {
  if (queries < 1) Fail("bench localize: --queries must be >= 1");
  instance.Check();
  localize.Check();
  for (const std::string& m : methods) FindMethod(m);
}

std::string CounterpartMethod(const MethodInfo& method) {
  for (const MethodInfo& other : AllMethods()) {
    if (other.lines != method.lines && other.multi == method.multi &&
        other.local_points == method.local_points && other.known_scale == method.known_scale &&
        other.gravity == method.gravity) {
      return std::string(other.name);
    }
  }
  return "";
}

namespace {

// RotationErrorBound of the true pose on the query's true inliers, in degrees.
double RotationBoundDeg(const MethodInfo& method, const LocalizationInstance& inst,
                        const LocalizationMap& map, double sigma_px) {
  const PreparedQuery prepared = PrepareQuery(method, inst.query, map);
  // The aligned frames' pose: query_from_world = query_from_aligned ∘ pose ∘
  // aligned_from_map (identities unless +u).
  const Sim3d aligned_truth =
      Sim3d(1.0, prepared.aligned_from_query, Eigen::Vector3d::Zero()) * inst.truth *
      Sim3d(1.0, prepared.aligned_from_map.inverse(), Eigen::Vector3d::Zero());
  std::vector<int> inliers;
  for (size_t i = 0; i < inst.is_inlier.size(); ++i) {
    if (inst.is_inlier[i]) inliers.push_back(static_cast<int>(i));
  }
  return RotationErrorBound(prepared.data, inliers, aligned_truth, sigma_px, method.similarity()) *
         180.0 / std::numbers::pi;
}

}  // namespace

std::vector<LocalizationBenchRow> RunLocalizationBench(
    const LocalizationBenchOptions& options,
    const std::function<void(const std::string&)>& progress) {
  options.Check();
  std::vector<LocalizationBenchRow> rows;
  for (const MethodInfo& method : AllMethods()) {
    if (!method.implemented) continue;
    if (!options.methods.empty() && std::find(options.methods.begin(), options.methods.end(),
                                              method.name) == options.methods.end()) {
      continue;
    }
    progress(fmt::format("{} ({} queries)", method.name, options.queries));
    LocalizationTally tally(options.max_rotation_deg, options.max_position_rel);
    LocalizeOptions localize = options.localize;
    // Poses are judged by their error to the truth, not by the criteria a
    // user without ground truth needs (and timing leaves out the calibration check).
    localize.success = SuccessCriteria::None();
    const std::string counterpart = CounterpartMethod(method);
    std::vector<double> bound, counterpart_bound;
    for (int k = 0; k < options.queries; ++k) {
      // Query k is the same for a method and its counterpart.
      std::mt19937_64 rng(options.seed * 1000003 + static_cast<uint64_t>(k));
      const LocalizationInstance inst = RandomLocalizationInstance(method, options.instance, rng);
      localize.ransac.seed = options.seed + static_cast<uint64_t>(k);
      const LocalizationMap map =
          method.lines ? LocalizationMap(inst.line_map) : LocalizationMap(inst.point_map);
      const LocalizeResult r = Localize(method, inst.query, map, localize);
      // Confident: a pose the user's criteria (not the benchmark's None) would accept.
      tally.Add(r, inst.truth, inst.scene_size, "",
                r.has_pose && SuccessFailure(method, r, options.localize.success).empty());
      if (options.instance.noise_px > 0) {
        const LocalizationMap other =
            method.lines ? LocalizationMap(inst.point_map) : LocalizationMap(inst.line_map);
        bound.push_back(RotationBoundDeg(method, inst, map, options.instance.noise_px));
        if (!counterpart.empty()) {
          counterpart_bound.push_back(
              RotationBoundDeg(FindMethod(counterpart), inst, other, options.instance.noise_px));
        }
      }
    }
    LocalizationBenchRow row;
    static_cast<LocalizationSummary&>(row) = tally.Summary();
    row.method = std::string(method.name);
    row.counterpart = counterpart;
    if (!bound.empty()) row.rotation_bound_deg = Median(bound);
    if (!counterpart_bound.empty()) row.counterpart_rotation_bound_deg = Median(counterpart_bound);
    rows.push_back(row);
  }
  return rows;
}

nlohmann::json LocalizationBenchRow::ToJson() const {
  return {
      {"method", method},
      {"queries", queries},
      {"localized", localized},
      {"confident_wrong", confident_wrong},
      {"median_rotation_deg",
       {{"initial", median_rotation_deg[0]}, {"refined", median_rotation_deg[1]}}},
      {"median_position_rel", {{"initial", median_position[0]}, {"refined", median_position[1]}}},
      {"iterations", iterations},
      {"inlier_ratio", inlier_ratio},
      {"mean_solutions", solutions},
      {"solver_us", solver_us},
      {"ransac_ms", ransac_ms},
      {"refine_ms", refine_ms},
      {"refine_iterations", refine_iterations},
      {"total_ms", total_ms},
      {"median_total_ms", median_total_ms},
      {"time_ms",
       {{"solver", solver_ms},
        {"scoring", scoring_ms},
        {"local_optimization", lo_ms},
        {"refinement", refine_ms}}},
      {"counterpart", counterpart},
      {"rotation_bound_deg", rotation_bound_deg},
      {"counterpart_rotation_bound_deg", counterpart_rotation_bound_deg}};
}

}  // namespace linecloud
