#include <cstdio>
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/eval/overlay.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/localize/image_query.h"
#include "linecloud/localize/localize.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

struct LocalizeArgs {
  std::string map_path;
  std::string model_dir;
  std::string query_path;
  std::string image_path;
  std::string camera;
  std::string database;
  ImageQueryOptions image;
  std::string method;
  bool no_refine = false;
  double threshold = 4.0;
  uint64_t seed = 0;
  std::string out;
  std::string format = "json";
  std::string ply;
  std::string overlay;
  std::string gravity, map_gravity;
  bool with_inliers = false;
  bool quiet = false;
  int min_inliers = -1;
  LocalizeOptions options;
};

void PrintProgress(int iterations, int needed, int inliers, double seconds) {
  std::cerr << fmt::format("\rRANSAC: {} iterations ({} needed), best {} inliers, {:.1f} s   ",
                           iterations, needed, inliers, seconds)
            << std::flush;
}

void RunLocalize(LocalizeArgs args) {
  // Default: the single-image method without gravity for the map's kind.
  if (args.method.empty()) args.method = args.map_path.empty() ? "p3P" : "p6L";
  const MethodInfo& method = FindMethod(args.method);
  if (args.map_path.empty() == args.model_dir.empty()) {
    Fail("give exactly one of --map MAP.lcm (line cloud) or --model DIR (point model)");
  }
  if (!args.overlay.empty() && args.image_path.empty()) {
    Fail("--overlay draws on the photo: it needs --image");
  }
  if (args.query_path.empty() == args.image_path.empty()) {
    Fail("give exactly one of --query QUERY.json (correspondences) or --image PHOTO (with "
         "--camera)");
  }
  std::optional<LineCloud> cloud;
  std::optional<Reconstruction> model;
  if (args.map_path.empty()) {
    model = ReadColmapModel(args.model_dir);
  } else {
    cloud = ReadLineCloud(args.map_path);
  }
  Query query;
  std::optional<ImageQuery> image_query;
  if (!args.image_path.empty()) {
    if (args.camera.empty()) Fail("--image needs --camera \"MODEL WIDTH HEIGHT PARAMS...\"");
    const Camera camera = ParseCameraString(args.camera);
    MapDescriptors descriptors;
    if (cloud) {
      descriptors = MapDescriptorsFromCloud(*cloud, args.map_path);
    } else {
      if (args.database.empty()) {
        Fail("--image with --model needs the model's --database colmap.db for descriptors");
      }
      descriptors = MapDescriptorsFromModel(*model, args.database);
    }
    if (!args.quiet) {
      args.image.progress = [](const std::string& what) { std::cerr << what << "\n"; };
    }
    image_query = QueryFromImage(args.image_path, camera, descriptors, args.image);
    query = image_query->query;
  } else {
    query = ReadQueryJson(args.query_path);
  }
  const std::string source = args.image_path.empty() ? args.query_path : args.image_path;
  // Gravity: the query's from --gravity, the map's from the .lcm (lift
  // --gravity) or --map-gravity; QUERY.json fields win when present.
  if (!args.gravity.empty() && !query.gravity_query) {
    query.gravity_query = ParseDirection(args.gravity, "--gravity");
  }
  if (!query.gravity_map) {
    if (!args.map_gravity.empty()) {
      query.gravity_map = ParseDirection(args.map_gravity, "--map-gravity");
    } else if (cloud && cloud->gravity) {
      query.gravity_map = cloud->gravity;
    }
  }
  const LocalizationMap map =
      model ? LocalizationMap(PointMapFromModel(*model)) : LocalizationMap(LineMapFromCloud(*cloud));
  LocalizeOptions& options = args.options;
  options.ransac.max_error = args.threshold;
  options.ransac.seed = args.seed;
  options.refine = !args.no_refine;
  if (args.min_inliers >= 0) {
    options.success.min_inliers_points = options.success.min_inliers_lines = args.min_inliers;
  }
  bool progress_shown = false;
  if (!args.quiet) {
    options.ransac.progress = [&](int iterations, int needed, int inliers, double seconds) {
      PrintProgress(iterations, needed, inliers, seconds);
      progress_shown = true;
    };
  }
  LocalizeResult result;
  if (image_query && query.observations.size() < static_cast<size_t>(method.sample_size)) {
    result.num_correspondences = static_cast<int>(query.observations.size());
    result.failure = fmt::format("{} matches, fewer than the {} the method's sample needs",
                                 query.observations.size(), method.sample_size);
  } else {
    result = Localize(method, query, map, options, source);
  }
  if (progress_shown) std::cerr << "\n";

  std::string text;
  if (args.format == "colmap") {
    if (query.cameras.size() != 1) {
      Fail("--format colmap writes one image's pose; this query has {} cameras (use JSON)",
           query.cameras.size());
    }
    text = result.success ? LocalizeResultToColmapImagesTxt(result, "query")
                          : "# no pose: " + result.failure + "\n";
  } else {
    nlohmann::ordered_json j = LocalizeResultToJson(method, result, args.with_inliers);
    if (image_query) {
      j["num_features"] = image_query->features.size();
      j["num_matches"] = image_query->matches.size();
      j["times_ms"] = {{"decode", image_query->times.decode_ms},
                       {"extract", image_query->times.extract_ms},
                       {"match", image_query->times.match_ms},
                       {"ransac", result.stats.ransac_ms},
                       {"refine", result.refine_ms}};
    }
    text = j.dump(2) + "\n";
  }
  if (image_query && !args.overlay.empty()) {
    WriteLocalizationOverlay(args.overlay, ReadGreyImage(args.image_path), query, result, map);
  }
  if (!args.ply.empty() && result.has_pose) {
    WriteLocalizationPly(args.ply, cloud ? &*cloud : nullptr, model ? &*model : nullptr,
                         LocalizedCameras(query, result), 0);
  }
  if (args.out.empty()) {
    std::cout << text;
  } else {
    WriteFileAtomically(args.out, [&](std::ostream& os) { os << text; });
  }
  if (!args.quiet && !result.success) std::cerr << "no pose: " << result.failure << "\n";
}

}  // namespace

void RegisterLocalizeCommand(CLI::App& app) {
  auto args = std::make_shared<LocalizeArgs>();
  CLI::App* cmd = app.add_subcommand(
      "localize",
      "Localize a query (QUERY.json) against a line cloud or a point model: RANSAC with the "
      "method's minimal solver, then LM refinement. Exit code 0 when it ran, with \"success\": "
      "false and a \"reason\" when the data do not support a pose; non-zero for bad input");
  auto* map = cmd->add_option("--map", args->map_path, "Line cloud (.lcm)");
  auto* model = cmd->add_option("--model", args->model_dir, "COLMAP sparse model folder");
  map->excludes(model);
  cmd->add_option("--query", args->query_path, "Query file of correspondences (SPEC.md)");
  cmd->add_option("--image", args->image_path,
                  "A photo to localize: SIFT as COLMAP computes it, matched to the map's "
                  "descriptors");
  cmd->add_option("--camera", args->camera,
                  "The photo's camera, \"MODEL WIDTH HEIGHT PARAMS...\" in COLMAP's order");
  cmd->add_option("--database", args->database,
                  "With --model and --image: the COLMAP database of the model (descriptors)");
  cmd->add_option("--max-ratio", args->image.matching.max_ratio,
                  "Lowe's ratio test on descriptor angles (COLMAP's default)")
      ->capture_default_str();
  cmd->add_flag("--cross-check", args->image.matching.cross_check,
                "Keep only mutual nearest neighbours");
  cmd->add_option("--gravity", args->gravity,
                  "Gravity direction x,y,z in the query's (camera or rig) frame, for +u methods");
  cmd->add_option("--map-gravity", args->map_gravity,
                  "Gravity direction x,y,z in the map frame (default: the one lift --gravity "
                  "stored in the .lcm)");
  cmd->add_option("--max-image-size", args->image.sift.max_image_size,
                  "Photos with a larger side are downscaled before SIFT (COLMAP's "
                  "SiftExtraction.max_image_size)")
      ->capture_default_str();
  cmd->add_option("--method", args->method,
                  "One of the 16 methods, e.g. p6L, p3P, m-P3P+l (default: p6L with --map, p3P "
                  "with --model)");
  cmd->add_flag("--no-refine", args->no_refine, "Skip the final LM refinement");
  cmd->add_flag("--refine-focal", args->options.refine_focal,
                "Refine the focal length with the pose (single camera; the given focal is a "
                "prior, e.g. from EXIF)");
  cmd->add_option("--threshold", args->threshold, "RANSAC inlier threshold in pixels")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "RANSAC seed")->capture_default_str();
  cmd->add_option("--max-iterations", args->options.ransac.max_iterations,
                  "RANSAC iteration cap")
      ->capture_default_str();
  cmd->add_option("--max-seconds", args->options.ransac.max_seconds,
                  "RANSAC time budget in seconds (0: none)")
      ->capture_default_str();
  cmd->add_option("--min-inliers", args->min_inliers,
                  "Inliers a pose needs (default: 30 on a point model, 60 on a line cloud)");
  cmd->add_option("--min-inlier-ratio", args->options.success.min_inlier_ratio,
                  "Share of the correspondences that must be inliers")
      ->capture_default_str();
  cmd->add_option("--max-rotation-uncertainty", args->options.success.max_rotation_uncertainty_deg,
                  "Largest estimated 1-sigma rotation uncertainty (degrees) of a success")
      ->capture_default_str();
  cmd->add_flag("--inliers", args->with_inliers, "Also list the inlier observation indices");
  cmd->add_option("--format", args->format,
                  "json, or colmap (an images.txt entry for COLMAP's tools)")
      ->check(CLI::IsMember({"json", "colmap"}))
      ->capture_default_str();
  cmd->add_option("--ply", args->ply, "Write the map and the localized camera frustum(s) as PLY");
  cmd->add_option("--overlay", args->overlay,
                  "With --image: a PNG of the photo with inlier keypoints (green), outliers (red) "
                  "and their map lines or points projected by the pose (yellow)");
  cmd->add_flag("--quiet", args->quiet, "No progress or notes on standard error");
  cmd->add_option("--out", args->out, "Write the result here instead of standard output");
  cmd->callback([args] { RunLocalize(*args); });
}

}  // namespace linecloud
