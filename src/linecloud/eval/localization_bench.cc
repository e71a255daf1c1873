#include "linecloud/eval/localization_bench.h"

#include <algorithm>

#include <fmt/format.h>

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
  std::vector<LocalizationBenchRow> rows;
  for (const MethodInfo& method : AllMethods()) {
    if (!method.implemented) continue;
    if (!options.methods.empty() &&
        std::find(options.methods.begin(), options.methods.end(), method.name) ==
            options.methods.end()) {
      continue;
    }
    progress(fmt::format("{} ({} queries)", method.name, options.queries));
    LocalizationTally tally(options.max_rotation_deg, options.max_position_rel);
    LocalizeOptions localize = options.localize;
    for (int k = 0; k < options.queries; ++k) {
      // Query k is the same for a method and its counterpart.
      std::mt19937_64 rng(options.seed * 1000003 + static_cast<uint64_t>(k));
      const LocalizationInstance inst = RandomLocalizationInstance(method, options.instance, rng);
      localize.ransac.seed = options.seed + static_cast<uint64_t>(k);
      const LocalizationMap map = method.lines ? LocalizationMap(inst.line_map)
                                               : LocalizationMap(inst.point_map);
      tally.Add(Localize(method, inst.query, map, localize), inst.truth, inst.scene_size);
    }
    LocalizationBenchRow row;
    static_cast<LocalizationSummary&>(row) = tally.Summary();
    row.method = std::string(method.name);
    row.counterpart = CounterpartMethod(method);
    rows.push_back(row);
  }
  return rows;
}

}  // namespace linecloud
