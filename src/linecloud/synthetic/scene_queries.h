// The synthetic room's queries for any of the 16 methods, as the demo and its
// tests use them: single images; rigs made of consecutive query images (a
// SLAM trajectory seen as one generalized camera); local points (+l) from the
// true points in the rig frame with depth noise, in an arbitrarily scaled
// frame unless the scale is known (+s); gravity from the scene; a share of
// the matches replaced by wrong map ids.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

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

}  // namespace linecloud
