#include <chrono>
#include <filesystem>
#include <iostream>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "linecloud/apps/commands.h"
#include "linecloud/benchmarks/scene_localization.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/json_util.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/synthetic/demo.h"
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

// Localizes the queries with every method against the map it needs: the line
// cloud as read back from disk, or the point model.
void PrintLocalizationTable(const DemoArgs& args, const SyntheticScene& scene, const DemoFiles& d) {
  const LocalizationMap line_map = d.lines;
  const LocalizationMap point_map = d.points;
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

void RunDemo(const DemoArgs& args) {
  const SyntheticScene scene = GenerateSyntheticScene(args.scene);
  const Reconstruction& model = scene.model;
  const DemoFiles d = WriteDemoFiles(scene, args.queries, args.out);
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
      args.scene.noise_px, model.points3D.size(), model.MeanTrackLength(), d.num_observations,
      d.model_dir, ToHex(d.key_fingerprint), d.num_lines, d.map_path, d.map_bytes,
      static_cast<double>(d.map_bytes) / d.num_lines, d.lift_ms, d.compact_path, d.compact_bytes,
      static_cast<double>(d.compact_bytes) / d.num_lines, d.max_relative_distance_full,
      d.max_relative_distance_compact, d.differing_lines, d.num_queries, d.mean_query_observations,
      d.queries_dir, d.num_rig_queries, d.rig_dir, d.model_ply, d.map_ply);
  PrintLocalizationTable(args, scene, d);
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
