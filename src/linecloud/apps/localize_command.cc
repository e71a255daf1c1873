#include <cstdio>
#include <filesystem>
#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/lifting/key_store.h"
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
  std::vector<std::string> image_paths;
  std::vector<std::string> cameras;
  std::string rig;
  bool exact_matching = false;
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
  // Default: the method without gravity for the map's kind and the photo count.
  if (args.method.empty()) {
    const bool several = args.image_paths.size() > 1;
    args.method = args.map_path.empty() ? (several ? "m-p3P" : "p3P") : (several ? "m-p6L" : "p6L");
  }
  const MethodInfo& method = FindMethod(args.method);
  if (args.map_path.empty() == args.model_dir.empty()) {
    Fail("give exactly one of --map MAP.lcm (line cloud) or --model DIR (point model)");
  }
  {
    std::vector<std::string> inputs = {args.map_path, args.model_dir, args.query_path,
                                       args.database, args.rig};
    inputs.insert(inputs.end(), args.image_paths.begin(), args.image_paths.end());
    for (const auto& [option, output] :
         {std::pair<const char*, const std::string&>{"--out", args.out},
          {"--ply", args.ply},
          {"--overlay", args.overlay}}) {
      if (!output.empty()) RefuseOutputOverInputs(output, inputs, option);
    }
  }
  if (!args.overlay.empty() && args.image_paths.size() != 1) {
    Fail("--overlay draws on one photo: it needs exactly one --image");
  }
  if (args.query_path.empty() == args.image_paths.empty()) {
    Fail(
        "give exactly one of --query QUERY.json (correspondences) or --image PHOTO (with "
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
  std::optional<PhotoQuery> photos;
  if (!args.image_paths.empty()) {
    if (!args.quiet) {
      args.image.progress = [](const std::string& what) { std::cerr << what << "\n"; };
    }
    if (model && args.database.empty()) {
      Fail("--image with --model needs the model's --database colmap.db for descriptors");
    }
    if (cloud && !args.exact_matching) {
      // The cache beside the map is authenticated with this user's secret: one
      // planted by someone else is rebuilt, never parsed. No key store: no cache.
      try {
        args.image.index_cache_key = KeyStore(KeyStore::DefaultDirectory()).CacheSecret();
        args.image.index_cache = args.map_path + ".flann";
      } catch (const Error& e) {
        if (!args.quiet) std::cerr << "descriptor index not cached: " << e.what() << "\n";
      }
    }
    if (args.exact_matching) args.image.approximate_from = 0;
    photos = QueryFromPhotos(args.image_paths, args.cameras, args.rig, method,
                             cloud ? MapDescriptorsFromCloud(*cloud, args.map_path)
                                   : MapDescriptorsFromModel(*model, args.database),
                             args.image);
    query = photos->query;
  } else {
    query = ReadQueryJson(args.query_path);
  }
  const std::string source = photos ? args.image_paths[0] : args.query_path;
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
  const LocalizationMap map = model ? LocalizationMap(PointMapFromModel(*model))
                                    : LocalizationMap(LineMapFromCloud(*cloud));
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
  if (photos && query.observations.size() < static_cast<size_t>(method.sample_size)) {
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
    const std::string name =
        photos ? std::filesystem::path(args.image_paths[0]).filename().string() : "query";
    text = result.success ? LocalizeResultToColmapImagesTxt(result, name)
                          : "# no pose: " + result.failure + "\n";
  } else {
    nlohmann::ordered_json j = LocalizeResultToJson(method, result, args.with_inliers);
    if (photos) {
      const ImageQueryTimes t = photos->times();
      AddPhotoStats(photos->num_features(), photos->num_matches(), t.decode_ms, t.extract_ms,
                    t.match_ms, result, &j);
    }
    text = j.dump(2) + "\n";
  }
  if (photos && !args.overlay.empty()) {
    WriteLocalizationOverlay(args.overlay, photos->photos[0].image, query, result, map);
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
  cmd->add_option("--image", args->image_paths,
                  "A photo to localize: SIFT as COLMAP computes it, matched to the map's "
                  "descriptors; repeat for the photos of a rig (with --rig)");
  cmd->add_option("--camera", args->cameras,
                  "The photo's camera, \"MODEL WIDTH HEIGHT PARAMS...\" in COLMAP's order; one "
                  "for all photos or one per photo");
  cmd->add_option("--rig", args->rig,
                  "Several photos: RIG.json {\"cam_from_rig\": [{\"q\": [w,x,y,z], \"t\": "
                  "[x,y,z]}, ...]}, one pose per --image");
  cmd->add_option("--database", args->database,
                  "With --model and --image: the COLMAP database of the model (descriptors)");
  cmd->add_option("--max-ratio", args->image.matching.max_ratio,
                  "Lowe's ratio test on descriptor angles (COLMAP's default)")
      ->capture_default_str();
  cmd->add_flag("--cross-check", args->image.matching.cross_check,
                "Keep only mutual nearest neighbours (exact matching)");
  cmd->add_option("--approximate-from", args->image.approximate_from,
                  "Maps with at least this many descriptors use the approximate index")
      ->capture_default_str();
  cmd->add_flag("--exact-matching", args->exact_matching,
                "Match exactly even on large maps (default: maps of 20 000 descriptors or more "
                "use the approximate index, cached as MAP.lcm.flann)");
  cmd->add_option("--gravity", args->gravity,
                  "Gravity direction x,y,z in the query's (camera or rig) frame, for +u methods");
  cmd->add_option("--map-gravity", args->map_gravity,
                  "Gravity direction x,y,z in the map frame (default: the one lift --gravity "
                  "stored in the .lcm)");
  cmd->add_option("--max-image-size", args->image.sift.max_image_size,
                  "Photos with a larger side are downscaled before SIFT (COLMAP's "
                  "SiftExtraction.max_image_size)")
      ->capture_default_str();
  cmd->add_option("--max-pixels", args->image.max_pixels,
                  "Photos (JPEG or PNG) whose header announces more pixels are refused before "
                  "decoding")
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
  cmd->add_option("--max-iterations", args->options.ransac.max_iterations, "RANSAC iteration cap")
      ->capture_default_str();
  cmd->add_option("--max-seconds", args->options.ransac.max_seconds,
                  "RANSAC time budget in seconds (0: none)")
      ->capture_default_str();
  cmd->add_flag("!--uniform-sampling", args->options.ransac.progressive_sampling,
                "Uniform RANSAC samples even when matches have Lowe ratios (--image, or \"ratio\" "
                "in QUERY.json); by default the best-ranked matches are tried first (PROSAC)");
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
