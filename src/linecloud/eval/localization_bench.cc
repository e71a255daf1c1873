#include "linecloud/eval/localization_bench.h"

#include <algorithm>
#include <numbers>

#include <fmt/format.h>

#include "linecloud/eval/statistics.h"
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

std::vector<LocalizationBenchRow> RunLocalizationBench(
    const LocalizationBenchOptions& options,
    const std::function<void(const std::string&)>& progress) {
  options.Check();
  constexpr double kDeg = 180.0 / std::numbers::pi;
  std::vector<LocalizationBenchRow> rows;
  for (const MethodInfo& method : AllMethods()) {
    if (!method.implemented) continue;
    if (!options.methods.empty() &&
        std::find(options.methods.begin(), options.methods.end(), method.name) ==
            options.methods.end()) {
      continue;
    }
    progress(fmt::format("{} ({} queries)", method.name, options.queries));
    LocalizationBenchRow row;
    row.method = std::string(method.name);
    row.counterpart = CounterpartMethod(method);
    std::vector<double> rotation[2], position[2];
    LocalizeOptions localize = options.localize;
    for (int k = 0; k < options.queries; ++k) {
      // Query k is the same for a method and its counterpart.
      std::mt19937_64 rng(options.seed * 1000003 + static_cast<uint64_t>(k));
      const LocalizationInstance inst = RandomLocalizationInstance(method, options.instance, rng);
      localize.ransac.seed = options.seed + static_cast<uint64_t>(k);
      const LocalizationMap map = method.lines ? LocalizationMap(inst.line_map)
                                               : LocalizationMap(inst.point_map);
      const LocalizeResult r = Localize(method, inst.query, map, localize);
      ++row.queries;
      row.iterations += r.stats.iterations;
      row.inlier_ratio += r.stats.inlier_ratio;
      row.solutions += r.stats.mean_solutions;
      row.solver_us += r.stats.solver_us;
      row.ransac_ms += r.stats.ransac_ms;
      row.refine_ms += r.refine_ms;
      row.refine_iterations += r.refine_iterations;
      const Sim3d* estimates[2] = {&r.initial, &r.query_from_world};
      for (int e = 0; e < 2; ++e) {
        LocalizationError err{std::numbers::pi, 1e9};
        if (r.success) err = CompareLocalization(*estimates[e], inst.truth);
        rotation[e].push_back(err.rotation_rad * kDeg);
        position[e].push_back(err.position / inst.scene_size);
      }
      row.localized += rotation[1].back() < options.max_rotation_deg &&
                       position[1].back() < options.max_position_rel;
    }
    const double n = row.queries;
    for (double* v : {&row.iterations, &row.inlier_ratio, &row.solutions, &row.solver_us,
                      &row.ransac_ms, &row.refine_ms, &row.refine_iterations}) {
      *v /= n;
    }
    row.total_ms = row.ransac_ms + row.refine_ms;
    for (int e = 0; e < 2; ++e) {
      row.median_rotation_deg[e] = Median(rotation[e]);
      row.median_position_rel[e] = Median(position[e]);
    }
    rows.push_back(row);
  }
  return rows;
}

}  // namespace linecloud
