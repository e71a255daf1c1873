// Localizing the synthetic room's queries (synthetic/scene_queries.h) with
// any of the 16 methods, as the demo does, summarised per method.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "linecloud/benchmarks/localization_summary.h"
#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/scene.h"
#include "linecloud/synthetic/scene_queries.h"

namespace linecloud {

struct MethodSummary : LocalizationSummary {
  std::string method;  // median_position in world units
};

// Runs `method` on every query; `localized` counts refined poses within
// max_rotation_deg and max_position (world units).
MethodSummary EvaluateMethod(const MethodInfo& method, const std::vector<SceneQuery>& queries,
                             const LocalizationMap& map, const LocalizeOptions& options,
                             double max_rotation_deg, double max_position);

}  // namespace linecloud
