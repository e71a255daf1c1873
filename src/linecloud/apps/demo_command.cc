#include <chrono>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/eval/scene_localization.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/synthetic/scene.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct DemoArgs {
  std::string out = "linecloud_demo";
  SyntheticSceneOptions scene;
  SceneQueryOptions queries;
};

// A query file in the format of `linecloud localize` (SPEC.md), plus the
// ground truth under "ground_truth" for evaluation.
// Each observation carries the point id (for --model) and the line id (for
// --map), as only the key's owner can write them.
void AddLineIds(const LiftingKey& key, Query* query) {
  std::vector<uint64_t> point_ids;
  for (const QueryObservation& o : query->observations) point_ids.push_back(o.id);
  const std::vector<uint64_t> line_ids = LineIdsOfPoints(key, point_ids);
  for (size_t i = 0; i < line_ids.size(); ++i) query->observations[i].line_id = line_ids[i];
}

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

void RunDemo(const DemoArgs& args) {
  using Clock = std::chrono::steady_clock;
  const SyntheticScene scene = GenerateSyntheticScene(args.scene);
  const Reconstruction& model = scene.model;
  CreateDirectories(args.out);
  const std::string model_dir = JoinPaths(args.out, "model");
  WriteColmapModel(model, model_dir, ModelFormat::kBinary);

  // The demo's fixed public key (compact256 directions): the same lines on
  // every run, and the full and compact maps hold identical lines.
  const std::string map_path = JoinPaths(args.out, "map.lcm");
  const LiftingKey key = DemoLiftingKey();

  // Lift from the model as written, exactly as `linecloud lift` would.
  const Reconstruction reread = ReadColmapModel(model_dir);
  const std::vector<uint64_t> ids = reread.SortedPoint3DIds();
  std::vector<Eigen::Vector3d> points;
  for (const uint64_t id : ids) points.push_back(reread.points3D.at(id).xyz);

  const auto t0 = Clock::now();
  const LineCloud cloud = LiftPoints(ids, points, key, {LineEncoding::kPlucker});
  const double lift_s = std::chrono::duration<double>(Clock::now() - t0).count();
  WriteLineCloud(cloud, map_path);
  const std::string compact_path = JoinPaths(args.out, "map_compact.lcm");
  WriteLineCloud(LiftPoints(ids, points, key, {LineEncoding::kCompact}), compact_path);

  // Verify what was written: every line passes through its point, and the
  // two files hold the same line for every point.
  const LineCloud full_back = ReadLineCloud(map_path);
  const LineCloud compact_back = ReadLineCloud(compact_path);
  const LineMap full_lines = LineMapByPointId(full_back, key);
  const LineMap compact_lines = LineMapByPointId(compact_back, key);
  const auto max_relative_distance = [&](const LineMap& m) {
    double worst = 0;
    for (size_t i = 0; i < ids.size(); ++i) {
      worst = std::max(worst,
                       m.lines.at(ids[i]).DistanceTo(points[i]) / std::max(1.0, points[i].norm()));
    }
    return worst;
  };
  size_t differing = 0;
  for (const uint64_t id : ids) {
    const PluckerLine& a = full_lines.lines.at(id);
    const PluckerLine& b = compact_lines.lines.at(id);
    differing += !(a.v == b.v && a.w == b.w);
  }

  const std::string queries_dir = JoinPaths(args.out, "queries");
  CreateDirectories(queries_dir);
  size_t total_obs = 0;
  for (const SyntheticQuery& q : scene.queries) {
    const std::string text = QueryJson(q, scene.gravity_in_world, key).dump(1);
    WriteFileAtomically(JoinPaths(queries_dir, q.name + ".json"),
                        [&](std::ostream& o) { o << text << "\n"; });
    total_obs += q.observations.size();
  }
  // Rig queries (3 consecutive query images, local points with depth noise,
  // metric): for the m- and +l methods.
  const std::string rig_dir = JoinPaths(args.out, "rig_queries");
  CreateDirectories(rig_dir);
  const std::vector<SceneQuery> rig_queries =
      SceneQueriesForMethod(scene, FindMethod("m-P3P+l+s"), args.queries);
  for (size_t k = 0; k < rig_queries.size(); ++k) {
    Query rig_query = rig_queries[k].query;
    AddLineIds(key, &rig_query);
    nlohmann::json j = QueryToJson(rig_query);
    j["ground_truth"] = {{"rig_from_world", PoseToJson(rig_queries[k].truth.rotation,
                                                       rig_queries[k].truth.translation)}};
    const std::string text = j.dump(1);
    WriteFileAtomically(JoinPaths(rig_dir, fmt::format("rig_{:03d}.json", k)),
                        [&](std::ostream& o) { o << text << "\n"; });
  }
  WriteModelPly(model, JoinPaths(args.out, "model.ply"));
  WriteLineCloudPly(cloud, JoinPaths(args.out, "map.ply"), 0.5);

  const size_t map_bytes = std::filesystem::file_size(map_path);
  const size_t compact_bytes = std::filesystem::file_size(compact_path);
  size_t num_obs = 0;
  for (const auto& [id, im] : model.images) num_obs += im.points2D.size();

  std::cout << fmt::format(
      "linecloud demo (seed {})\n"
      "  scene        room {:.0f} x {:.0f} x {:.0f} m, {} map images, camera "
      "SIMPLE_RADIAL {}x{} f={:.0f}, {:.1f} px noise\n"
      "  model        {} points (mean track {:.2f}), {} observations -> {}\n"
      "  key          the built-in public demo key (compact256 directions; never for real "
      "maps), fingerprint {}\n"
      "  line cloud   {} lines -> {} ({} bytes, {:.1f} B/line), lifted in "
      "{:.2f} ms\n"
      "  compact      {} ({} bytes, {:.1f} B/line)\n"
      "  check        max point-to-line distance / |X|: full {:.2e}, "
      "compact {:.2e}; lines differing between the two files: {}\n"
      "  queries      {} query files ({:.0f} observations on average) -> {}\n"
      "               {} rig query files (3 images, local points) -> {}\n"
      "  view         {} (points), {} (line segments)\n",
      args.scene.seed, args.scene.room_size.x(), args.scene.room_size.y(), args.scene.room_size.z(),
      model.images.size(), args.scene.width, args.scene.height, args.scene.focal,
      args.scene.noise_px, model.points3D.size(), model.MeanTrackLength(), num_obs, model_dir,
      ToHex(cloud.key_fingerprint), cloud.size(), map_path, map_bytes,
      static_cast<double>(map_bytes) / cloud.size(), 1e3 * lift_s, compact_path, compact_bytes,
      static_cast<double>(compact_bytes) / cloud.size(), max_relative_distance(full_lines),
      max_relative_distance(compact_lines), differing, scene.queries.size(),
      scene.queries.empty() ? 0.0 : static_cast<double>(total_obs) / scene.queries.size(),
      queries_dir, rig_queries.size(), rig_dir, JoinPaths(args.out, "model.ply"),
      JoinPaths(args.out, "map.ply"));

  // Localize the queries with every method against the map it needs: the
  // line cloud as read back from disk, or the point model.
  const LocalizationMap line_map = full_lines;
  const LocalizationMap point_map = PointMapFromModel(reread);
  LocalizeOptions options;
  const double max_position = 0.01 * scene.extent;
  std::cout << fmt::format(
      "\nlocalization: {:.0f} % wrong matches, 1 px noise, +l points with {:.1f} % depth noise; "
      "localized = refined pose within 1 deg and {:.2f} m (1 % of the room)\n",
      100 * args.queries.outlier_ratio, 100 * args.queries.local_noise, max_position);
  std::cout << "| method | map | queries | localized | rot. deg init / ref | pos. m init / ref "
               "| inliers | iters | sols | solver us | ms/query | reproj. px init / ref |\n"
               "|---|---|---|---|---|---|---|---|---|---|---|---|\n";
  std::vector<std::string> failures;
  for (const MethodInfo& method : AllMethods()) {
    if (!method.implemented) {
      std::cout << fmt::format("| {} | {} | no solver yet | | | | | | | | | |\n", method.name,
                               method.lines ? "lines" : "points");
      continue;
    }
    const std::vector<SceneQuery> queries = SceneQueriesForMethod(scene, method, args.queries);
    const MethodSummary m = EvaluateMethod(method, queries, method.lines ? line_map : point_map,
                                           options, 1.0, max_position);
    std::cout << fmt::format(
        "| {} | {} | {} | {} | {:.3f} / {:.3f} | {:.3f} / {:.3f} | {:.0f} % | {:.0f} | {:.2f} | "
        "{:.2f} | {:.2f} | {:.2f} / {:.2f} |\n",
        m.method, method.lines ? "lines" : "points", m.queries, m.localized,
        m.median_rotation_deg[0], m.median_rotation_deg[1], m.median_position[0],
        m.median_position[1], 100 * m.inlier_ratio, m.iterations, m.solutions, m.solver_us,
        m.total_ms, m.reprojection_px[0], m.reprojection_px[1]);
    for (const std::string& f : m.failures) failures.push_back(m.method + " " + f);
  }
  // Queries without a pose, and why (the success criteria of `localize`).
  for (const std::string& f : failures) std::cout << "no pose: " << f << "\n";
}

}  // namespace

void RegisterDemoCommand(CLI::App& app) {
  auto args = std::make_shared<DemoArgs>();
  CLI::App* cmd =
      app.add_subcommand("demo",
                         "Generate a seeded synthetic room, write it as a COLMAP model, lift it "
                         "to a line cloud and summarise");
  cmd->add_option("--out", args->out, "Output folder")->capture_default_str();
  cmd->add_option("--seed", args->scene.seed, "Random seed")->capture_default_str();
  cmd->add_option("--points", args->scene.num_points, "Number of scene points")
      ->capture_default_str();
  cmd->add_option("--images", args->scene.num_map_images, "Number of map images")
      ->capture_default_str();
  cmd->add_option("--queries", args->scene.num_queries, "Number of query images")
      ->capture_default_str();
  cmd->add_option("--noise", args->scene.noise_px, "2D noise std. dev. (px)")
      ->capture_default_str();
  cmd->add_option("--outliers", args->queries.outlier_ratio,
                  "Share of query matches replaced by wrong map ids")
      ->capture_default_str();
  cmd->callback([args] { RunDemo(*args); });
}

}  // namespace linecloud
