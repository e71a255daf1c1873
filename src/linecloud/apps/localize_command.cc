#include <cstdio>
#include <filesystem>

#include <iostream>
#include <memory>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/apps/localizer_flags.h"
#include "linecloud/draw/overlay.h"
#include "linecloud/features/sift_opencv.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/io/lcm_format.h"
#include "linecloud/io/ply.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/localize.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/pipeline/localizer_result_json.h"
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
  std::string database;
  std::string method;
  std::string out;
  std::string format = "json";
  std::string ply;
  std::string overlay;
  std::string gravity;
  bool with_inliers = false;
  bool quiet = false;
  LocalizerFlags options;  // every option of localizer_option_table.h
};

void PrintProgress(int iterations, int needed, int inliers, double seconds) {
  std::cerr << fmt::format("\rRANSAC: {} iterations ({} needed), best {} inliers, {:.1f} s   ",
                           iterations, needed, inliers, seconds)
            << std::flush;
}

void CheckArgs(const LocalizeArgs& args) {
  if (args.map_path.empty() == args.model_dir.empty()) {
    Fail("give exactly one of --map MAP.lcm (line cloud) or --model DIR (point model)");
  }
  std::vector<std::string> inputs = {args.map_path, args.model_dir, args.query_path, args.database,
                                     args.rig};
  inputs.insert(inputs.end(), args.image_paths.begin(), args.image_paths.end());
  for (const auto& [option, output] :
       {std::pair<const char*, const std::string&>{"--out", args.out},
        {"--ply", args.ply},
        {"--overlay", args.overlay}}) {
    if (!output.empty()) RefuseOutputOverInputs(output, inputs, option);
  }
  if (!args.overlay.empty() && args.image_paths.size() != 1) {
    Fail("--overlay draws on one photo: it needs exactly one --image");
  }
  if (args.query_path.empty() == args.image_paths.empty()) {
    Fail(
        "give exactly one of --query QUERY.json (correspondences) or --image PHOTO (with "
        "--camera)");
  }
  if (!args.image_paths.empty() && !args.model_dir.empty() && args.database.empty()) {
    Fail("--image with --model needs the model's --database colmap.db for descriptors");
  }
}

// The Localizer's options from the command line: the option table's flags,
// the index cache in the user's cache folder (authenticated with this user's
// secret; no key store, no cache), progress on standard error.
LocalizerOptions MakeLocalizerOptions(const LocalizeArgs& args) {
  LocalizerOptions o;
  args.options.Apply(&o);
  SetOpenCVThreads(o.image.threads);
  if (!args.map_path.empty() && !args.image_paths.empty()) {
    if (const auto note = UseIndexCache(args.map_path, &o); note && !args.quiet) {
      std::cerr << *note << "\n";
    }
  }
  if (!args.quiet) o.progress = [](const std::string& what) { std::cerr << what << "\n"; };
  return o;
}

// The photos of --image with their --camera strings and --rig poses.
std::vector<QueryPhoto> ReadPhotos(const LocalizeArgs& args, const MethodInfo& method,
                                   const std::optional<RigFile>& rig,
                                   std::vector<std::string>* bytes) {
  const size_t n = args.image_paths.size();
  if (args.cameras.empty()) Fail("--image needs --camera \"MODEL WIDTH HEIGHT PARAMS...\"");
  if (args.cameras.size() != 1 && args.cameras.size() != n) {
    Fail("{} photos but {} --camera strings (give one for all, or one per photo)", n,
         args.cameras.size());
  }
  if (n > 1 && !rig) Fail("{} photos need --rig RIG.json (their cam_from_rig poses)", n);
  // The method before the rig's size (as before the Localizer): the more basic mistake first.
  if (n > 1 && !method.multi) {
    Fail("{} photos make one generalized camera: use an m- method (m-p6L, m-p3P, ...), not {}", n,
         method.name);
  }
  if (rig && rig->cam_from_rig.size() != n) {
    Fail("{} photos but {} cam_from_rig poses in {}", n, rig->cam_from_rig.size(), args.rig);
  }
  std::vector<QueryPhoto> photos(n);
  bytes->resize(n);
  for (size_t k = 0; k < n; ++k) {
    photos[k].camera = ParseCameraString(args.cameras[args.cameras.size() == 1 ? 0 : k]);
    if (rig) photos[k].cam_from_rig = rig->cam_from_rig[k];
    photos[k].name = args.image_paths[k];
  }
  for (size_t k = 0; k < n; ++k) {
    (*bytes)[k] = ReadFileToString(args.image_paths[k]);
    photos[k].encoded =
        std::span(reinterpret_cast<const uint8_t*>((*bytes)[k].data()), (*bytes)[k].size());
  }
  return photos;
}

// The request: --method, --gravity and what RIG.json adds (local points, their scale, gravity).
LocalizeRequest MakeRequest(const LocalizeArgs& args, const std::optional<RigFile>& rig) {
  LocalizeRequest request;
  request.method = args.method;
  request.keep_images = !args.overlay.empty();
  if (!args.gravity.empty()) request.gravity = ParseDirection(args.gravity, "--gravity");
  if (rig) {
    if (rig->gravity && request.gravity) {
      Fail("--gravity and {}'s gravity: give the rig's gravity once", args.rig);
    }
    if (rig->gravity) request.gravity = rig->gravity;
    request.points_local = rig->points_local;
    request.scale_known = rig->scale_known;
  }
  return request;
}

// A few lines for people: the pose, its support and uncertainty, or why there is none.
std::string ResultText(const LocalizerResult& r) {
  const LocalizeResult& p = r.pose;
  const double ratio = p.num_correspondences > 0
                           ? 100.0 * static_cast<double>(p.inliers.size()) / p.num_correspondences
                           : 0.0;
  const std::string support =
      fmt::format("{} inliers of {} matches ({:.0f} %), {} in {:.0f} ms", p.inliers.size(),
                  p.num_correspondences, ratio, r.method, r.times.total_ms);
  if (!r.success()) return fmt::format("no pose: {}\n({})\n", r.reason, support);
  const Sim3d& pose = p.query_from_world;
  const Eigen::Quaterniond& q = pose.rotation;
  const Eigen::Vector3d centre = pose.Inverse().translation;
  return fmt::format(
      "pose found: {}\n"
      "cam_from_world  q (w, x, y, z) = {:.6f} {:.6f} {:.6f} {:.6f}\n"
      "                t = {:.4f} {:.4f} {:.4f}{}\n"
      "camera centre   {:.4f} {:.4f} {:.4f} (map units)\n"
      "uncertainty     {:.3f}°, {:.3g} map units (1 σ)\n",
      support, q.w(), q.x(), q.y(), q.z(), pose.translation.x(), pose.translation.y(),
      pose.translation.z(), pose.scale != 1 ? fmt::format(", scale {:.6g}", pose.scale) : "",
      centre.x(), centre.y(), centre.z(), p.uncertainty.rotation_deg, p.uncertainty.position);
}

std::string FormatResult(const LocalizeArgs& args, const LocalizerResult& r) {
  if (args.format == "text") return ResultText(r);
  if (args.format == "colmap") {
    if (r.query.cameras.size() != 1) {
      Fail("--format colmap writes one image's pose; this query has {} cameras (use JSON)",
           r.query.cameras.size());
    }
    // The image's name: the photo's, or the query file's own stem.
    const std::string name = r.photos.empty()
                                 ? std::filesystem::path(args.query_path).stem().string()
                                 : std::filesystem::path(args.image_paths[0]).filename().string();
    return r.success() ? LocalizeResultToColmapImagesTxt(r.pose, name)
                       : "# no pose: " + r.reason + "\n";
  }
  return LocalizerResultToJson(r, args.with_inliers).dump(2) + "\n";
}

void RunLocalize(const LocalizeArgs& args) {
  CheckArgs(args);
  std::optional<LineCloud> cloud;
  std::optional<Reconstruction> model;
  if (args.map_path.empty()) {
    model = ReadColmapModel(args.model_dir);
  } else {
    cloud = ReadLineCloud(args.map_path);
    if (args.image_paths.empty()) {
      // A QUERY.json names its lines: the descriptors (and their index,
      // 0.9 s on fountain) are never used.
      cloud->descriptor_dim = 0;
      cloud->descriptors.clear();
    }
  }
  const LocalizerOptions options = MakeLocalizerOptions(args);
  const Localizer localizer = cloud
                                  ? Localizer(*cloud, options, args.map_path)
                                  : Localizer(*model, args.image_paths.empty() ? "" : args.database,
                                              options, args.model_dir);
  if (!args.rig.empty() && args.image_paths.empty()) {
    Fail("--rig goes with --image (a QUERY.json has its own cam_from_rig and points_local)");
  }
  const std::optional<RigFile> rig =
      args.rig.empty() ? std::nullopt : std::optional<RigFile>(ReadRigJson(args.rig));
  LocalizeRequest request = MakeRequest(args, rig);
  bool progress_shown = false;
  if (!args.quiet) {
    request.progress = options.progress;
    request.ransac_progress = [&](int iterations, int needed, int inliers, double seconds) {
      PrintProgress(iterations, needed, inliers, seconds);
      progress_shown = true;
    };
  }
  std::vector<std::string> bytes;
  // A rig: several photos, or one placed in a rig by RIG.json.
  const bool is_rig = args.image_paths.size() > 1 ||
                      (rig && !rig->cam_from_rig.empty() && !rig->cam_from_rig[0].IsIdentity());
  const LocalizerResult r =
      args.image_paths.empty()
          ? localizer.LocalizeQuery(ReadQueryJson(args.query_path), request, args.query_path)
          : localizer.LocalizePhotos(
                ReadPhotos(args, localizer.RequestMethod(is_rig, request), rig, &bytes), request);
  if (progress_shown) std::cerr << "\n";
  const std::string text = FormatResult(args, r);
  if (!args.overlay.empty()) {
    WriteLocalizationOverlay(args.overlay, r.photos[0].image, r.query, r.pose, localizer.map());
  }
  if (!args.ply.empty() && r.pose.has_pose) {
    WriteLocalizationPly(args.ply, cloud ? &*cloud : nullptr, model ? &*model : nullptr,
                         LocalizedCameras(r.query, r.pose), 0);
  }
  if (args.out.empty()) {
    std::cout << text;
  } else {
    WriteFileAtomically(args.out, [&](std::ostream& os) { os << text; });
  }
  if (!args.quiet && !r.success()) std::cerr << "no pose: " << r.reason << "\n";
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
  cmd->add_option("--query", args->query_path,
                  "Query file of correspondences (docs/formats.md, QUERY.json)");
  cmd->add_option("--image", args->image_paths,
                  "A photo to localize: SIFT as COLMAP computes it, matched to the map's "
                  "descriptors; repeat for the photos of a rig (with --rig)");
  cmd->add_option("--camera", args->cameras,
                  "The photo's camera, \"MODEL WIDTH HEIGHT PARAMS...\" in COLMAP's order; one "
                  "for all photos or one per photo");
  cmd->add_option("--rig", args->rig,
                  "A device's frames: RIG.json {\"cam_from_rig\": [{\"q\": [w,x,y,z], \"t\": "
                  "[x,y,z]}, ...] (one per --image), optional \"points_local\": [{\"frame\", "
                  "\"keypoint\", \"xyz\"}, ...] (+l methods), \"scale_known\", \"gravity\"} "
                  "(docs/formats.md)");
  cmd->add_option("--database", args->database,
                  "With --model and --image: the COLMAP database of the model (descriptors)");
  cmd->add_option("--gravity", args->gravity,
                  "Gravity direction x,y,z in the query's (camera or rig) frame, for +u methods");
  cmd->add_option("--method", args->method,
                  "One of the 16 methods, e.g. p6L, p3P, m-P3P+l (default: the one that uses what "
                  "is given: p6L with --map, p3P with --model; m- for several photos, +u with "
                  "gravity here and in the map, +l with RIG.json's points_local, +s when "
                  "scale_known)");
  constexpr OptionScope kAll[] = {OptionScope::kMap, OptionScope::kRequest};
  args->options.Add(cmd, kAll);
  cmd->add_flag("--inliers", args->with_inliers, "Also list the inlier observation indices");
  cmd->add_option("--format", args->format,
                  "json, text (a few lines for people), or colmap (an images.txt entry for "
                  "COLMAP's tools)")
      ->check(CLI::IsMember({"json", "text", "colmap"}))
      ->capture_default_str();
  cmd->add_option("--ply", args->ply, "Write the map and the localized camera frustum(s) as PLY");
  cmd->add_option("--overlay", args->overlay,
                  "With --image: a PNG of the photo with inlier keypoints (sky blue), outliers "
                  "(vermilion) and their map lines or points projected by the pose (yellow)");
  cmd->add_flag("--quiet", args->quiet, "No progress or notes on standard error");
  cmd->add_option("--out", args->out, "Write the result here instead of standard output");
  cmd->callback([args] { RunLocalize(*args); });
}

}  // namespace linecloud
