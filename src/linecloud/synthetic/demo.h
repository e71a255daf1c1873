// What `linecloud demo` writes, as a library call: the synthetic room as a
// COLMAP model, lifted with the fixed public demo key to a full and a compact
// line cloud (read back and verified: every line through its point, the same
// line in both files), query files for every method (with point and line ids,
// as only the key's owner can write them, and the ground truth), rig queries,
// and PLY files to look at.
#pragma once

#include <string>

#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/scene.h"
#include "linecloud/synthetic/scene_queries.h"

namespace linecloud {

struct DemoFiles {
  std::string model_dir, map_path, compact_path, queries_dir, rig_dir, model_ply, map_ply;
  size_t map_bytes = 0, compact_bytes = 0;
  size_t num_observations = 0;  // of the model
  double lift_ms = 0;
  // Verification of the files as read back: max point-to-line distance / |X|
  // (full, compact) and the lines that differ between the two files.
  double max_relative_distance_full = 0, max_relative_distance_compact = 0;
  size_t differing_lines = 0;
  size_t num_queries = 0, num_rig_queries = 0;
  double mean_query_observations = 0;
  LiftingKey::Id key_fingerprint{};
  size_t num_lines = 0;
  // The maps the queries are localized against: the line cloud as read back
  // from disk (keyed by point id: the demo's queries carry point ids) and the
  // point model as written.
  LineMap lines;
  PointMap points;
};

DemoFiles WriteDemoFiles(const SyntheticScene& scene, const SceneQueryOptions& queries,
                         const std::string& out_dir);

}  // namespace linecloud
