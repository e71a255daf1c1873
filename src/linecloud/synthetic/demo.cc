#include "linecloud/synthetic/demo.h"

#include <algorithm>
#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

// Each observation carries the point id (for --model) and the line id (for
// --map), as only the key's owner can write them.
void AddLineIds(const LiftingKey& key, Query* query) {
  std::vector<uint64_t> point_ids;
  for (const QueryObservation& o : query->observations) point_ids.push_back(o.id);
  const std::vector<uint64_t> line_ids = LineIdsOfPoints(key, point_ids);
  for (size_t i = 0; i < line_ids.size(); ++i) query->observations[i].line_id = line_ids[i];
}

// A query file in the format of `linecloud localize` (docs/formats.md), plus the
// ground truth under "ground_truth".
nlohmann::json QueryJson(const SyntheticQuery& q, const Eigen::Vector3d& gravity_world,
                         const LiftingKey& key) {
  Query query;
  query.cameras = {q.camera};
  for (const SyntheticObservation& o : q.observations) {
    query.observations.push_back({0, o.xy, o.point3D_id, std::nullopt, std::nullopt});
  }
  AddLineIds(key, &query);
  query.gravity_query = q.gravity_in_cam;
  query.gravity_map = gravity_world;
  nlohmann::json j = QueryToJson(query);
  j["ground_truth"] = {
      {"cam_from_world", PoseToJson(q.cam_from_world.rotation, q.cam_from_world.translation)}};
  return j;
}

void WriteJson(const std::string& path, const nlohmann::json& j) {
  const std::string text = j.dump(1);
  WriteFileAtomically(path, [&](std::ostream& o) { o << text << "\n"; });
}

// Every line through its point (max distance / |X|), by point id.
double MaxRelativeDistance(const LineMap& m, const std::vector<uint64_t>& ids,
                           const std::vector<Eigen::Vector3d>& points) {
  double worst = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    worst =
        std::max(worst, m.lines.at(ids[i]).DistanceTo(points[i]) / std::max(1.0, points[i].norm()));
  }
  return worst;
}

// The two maps, lifted from the model as written (exactly as `linecloud lift`
// would), read back and compared.
void LiftAndVerify(const std::string& model_dir, DemoFiles* d) {
  const LiftingKey key = DemoLiftingKey();
  const Reconstruction reread = ReadColmapModel(model_dir);
  const std::vector<uint64_t> ids = reread.SortedPoint3DIds();
  const std::vector<Eigen::Vector3d> points = PointCoordinates(reread, ids);
  const auto t0 = std::chrono::steady_clock::now();
  const LineCloud cloud = LiftPoints(ids, points, key, {LineEncoding::kPlucker});
  d->lift_ms = 1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  WriteLineCloud(cloud, d->map_path);
  WriteLineCloud(LiftPoints(ids, points, key, {LineEncoding::kCompact}), d->compact_path);
  d->key_fingerprint = cloud.key_fingerprint;
  d->num_lines = cloud.size();
  d->lines = LineMapByPointId(ReadLineCloud(d->map_path), key);
  const LineMap compact = LineMapByPointId(ReadLineCloud(d->compact_path), key);
  d->max_relative_distance_full = MaxRelativeDistance(d->lines, ids, points);
  d->max_relative_distance_compact = MaxRelativeDistance(compact, ids, points);
  for (const uint64_t id : ids) {
    const PluckerLine& a = d->lines.lines.at(id);
    const PluckerLine& b = compact.lines.at(id);
    d->differing_lines += !(a.v == b.v && a.w == b.w);
  }
  d->points = PointMapFromModel(reread);
  WriteLineCloudPly(cloud, d->map_ply, 0.5);
}

}  // namespace

DemoFiles WriteDemoFiles(const SyntheticScene& scene, const SceneQueryOptions& queries,
                         const std::string& out_dir) {
  DemoFiles d;
  CreateDirectories(out_dir);
  d.model_dir = JoinPaths(out_dir, "model");
  d.map_path = JoinPaths(out_dir, "map.lcm");
  d.compact_path = JoinPaths(out_dir, "map_compact.lcm");
  d.queries_dir = JoinPaths(out_dir, "queries");
  d.rig_dir = JoinPaths(out_dir, "rig_queries");
  d.model_ply = JoinPaths(out_dir, "model.ply");
  d.map_ply = JoinPaths(out_dir, "map.ply");
  WriteColmapModel(scene.model, d.model_dir, ModelFormat::kBinary);
  for (const auto& [id, im] : scene.model.images) d.num_observations += im.points2D.size();
  LiftAndVerify(d.model_dir, &d);

  const LiftingKey key = DemoLiftingKey();
  CreateDirectories(d.queries_dir);
  size_t total = 0;
  for (const SyntheticQuery& q : scene.queries) {
    WriteJson(JoinPaths(d.queries_dir, q.name + ".json"),
              QueryJson(q, scene.gravity_in_world, key));
    total += q.observations.size();
  }
  d.num_queries = scene.queries.size();
  d.mean_query_observations = d.num_queries ? static_cast<double>(total) / d.num_queries : 0.0;
  // Rig queries (3 consecutive query images, local points with depth noise,
  // metric): for the m- and +l methods.
  CreateDirectories(d.rig_dir);
  const std::vector<SceneQuery> rigs =
      SceneQueriesForMethod(scene, FindMethod("m-P3P+l+s"), queries);
  for (size_t k = 0; k < rigs.size(); ++k) {
    Query rig_query = rigs[k].query;
    AddLineIds(key, &rig_query);
    nlohmann::json j = QueryToJson(rig_query);
    j["ground_truth"] = {
        {"rig_from_world", PoseToJson(rigs[k].truth.rotation, rigs[k].truth.translation)}};
    WriteJson(JoinPaths(d.rig_dir, fmt::format("rig_{:03d}.json", k)), j);
  }
  d.num_rig_queries = rigs.size();
  WriteModelPly(scene.model, d.model_ply);
  d.map_bytes = std::filesystem::file_size(d.map_path);
  d.compact_bytes = std::filesystem::file_size(d.compact_path);
  return d;
}

}  // namespace linecloud
