// Localizing the synthetic room's queries with any of the 16 methods, as the
// demo does: single images; rigs made of consecutive query images (a SLAM
// trajectory seen as one generalized camera); local points (+l) from the
// true points in the rig frame with depth noise, in an arbitrarily scaled
// frame unless the scale is known (+s); gravity from the scene; a share of
// the matches replaced by wrong map ids.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "linecloud/eval/localization_summary.h"
#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/scene.h"

namespace linecloud {

struct SceneQueryOptions {
  double outlier_ratio = 0.3;  // share of observations matched to a wrong map id
  double local_noise = 0.005;  // +l point noise, relative to depth
  int rig_size = 3;            // images per m- query
  double local_scale = 0.37;   // scale of the +l frame when the scale is unknown
  uint64_t seed = 1;

  void Check() const;
};

struct SceneQuery {
  std::string name;
  Query query;
  Sim3d truth;  // query_from_world
};

std::vector<SceneQuery> SceneQueriesForMethod(const SyntheticScene& scene, const MethodInfo& method,
                                              const SceneQueryOptions& options);

struct MethodSummary : LocalizationSummary {
  std::string method;  // median_position in world units
};

// Runs `method` on every query; `localized` counts refined poses within
// max_rotation_deg and max_position (world units).
MethodSummary EvaluateMethod(const MethodInfo& method, const std::vector<SceneQuery>& queries,
                             const LocalizationMap& map, const LocalizeOptions& options,
                             double max_rotation_deg, double max_position);

}  // namespace linecloud
