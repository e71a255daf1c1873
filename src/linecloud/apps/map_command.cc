#include <iostream>
#include <thread>

#include <fmt/format.h>

#include "linecloud/apps/commands.h"
#include "linecloud/mapping/map_project.h"
#include "linecloud/util/log.h"

namespace linecloud {
namespace {

struct MapArgs {
  MapOptions options;
  std::string pairs = "auto";
  int threads = 0;
  bool no_audit = false;
  bool json = false;
};

void PrintSummary(const MapReport& r) {
  std::cout << fmt::format(
      "map: {} of {} photos registered, {} points (mean track length {:.2f}, reprojection error "
      "{:.2f} px), {} lines",
      r.registered, r.photos, r.points, r.mean_track_length, r.mean_reprojection_error_px, r.lines);
  if (r.update) {
    std::cout << fmt::format(" ({} released lines kept, {} new, {} withdrawn)", r.lines_kept,
                             r.lines_new, r.lines_withdrawn);
  }
  std::cout << "\n";
  for (const auto& [name, why] : r.unregistered) {
    std::cout << fmt::format("  not registered: {}: {}\n", name, why);
  }
  for (const MapStage& s : r.stages) {
    if (s.name != "audit") continue;
    const auto& d = s.details;
    if (d.contains("density_attack") && d["density_attack"].contains("recovery")) {
      std::cout << "audit: " << d["density_attack"]["recovery"].dump() << "\n";
    }
  }
  if (!r.map.empty()) {
    std::cout << fmt::format("served files: {}, {}{}{}\n", r.map, r.map_json,
                             r.map_audit.empty() ? "" : ", ", r.map_audit);
  }
  std::cout << fmt::format("project: {} (report.json; private: never serve it)\n", r.project);
}

void RunMap(MapArgs args) {
  MapOptions& o = args.options;
  o.sfm.pairs = ParsePairSelection(args.pairs, "--pairs");
  o.sfm.threads =
      args.threads > 0 ? args.threads : int(std::max(1u, std::thread::hardware_concurrency()));
  o.audit = !args.no_audit;
  // Progress on stderr, line by line: stdout holds the result alone (--json).
  const ScopedLogSink progress_to_stderr(
      [](LogLevel, std::string_view line) { std::cerr << line << std::endl; });
  const MapReport r = BuildMap(o);
  if (args.json) {
    std::cout << r.ToJson().dump(1) << "\n";
  } else {
    PrintSummary(r);
  }
}

}  // namespace

void RegisterMapCommand(CLI::App& app) {
  auto args = std::make_shared<MapArgs>();
  MapOptions& o = args->options;
  CLI::App* cmd = app.add_subcommand(
      "map",
      "Photos to a served map: SIFT, pairs, COLMAP's mapper, lift (the owner's key), audit; "
      "resumes where an interrupted run stopped");
  cmd->add_option("photos", o.photos, "photos (JPEG, PNG) or folders of them")->required();
  cmd->add_option("--project", o.project_dir,
                  "private project folder (features, database, point model, reports)")
      ->required();
  cmd->add_option("--camera", o.cameras,
                  "camera of the photos of its size, COLMAP's \"MODEL W H PARAMS...\", or of "
                  "the photos whose name matches a glob: \"*_c0.png=MODEL W H PARAMS...\" "
                  "(repeat for each; default: the EXIF, refined by the mapper)");
  cmd->add_option("--stereo", o.stereo,
                  "A,B,METRES: a calibrated stereo rig (the photo named with A replaced by B is "
                  "the other camera's, METRES apart): the map in metres");
  cmd->add_option("--out", o.out,
                  "the served map: MAPS_DIR/ID writes ID.lcm, ID.json, ID.audit.json there");
  cmd->add_flag("--update", o.update,
                "register new photos into the released map; every released point keeps its line");
  cmd->add_option("--pairs", args->pairs,
                  "auto (exhaustive up to 100 photos, else vocab-tree), exhaustive, vocab-tree, "
                  "sequential (frames of a video)")
      ->capture_default_str();
  cmd->add_option("--threads", args->threads, "threads (default: all cores)");
  cmd->add_option("--key-store", o.key_store,
                  "key store (default: $LINECLOUD_KEY_STORE or ~/.local/share/linecloud/keys)");
  cmd->add_option("--key-file", o.key_file,
                  "the map's secret key (created there if missing; default: the project's key in "
                  "the key store)");
  cmd->add_option("--colmap", o.sfm.colmap.executable, "COLMAP executable")->capture_default_str();
  cmd->add_option("--seed", o.sfm.seed, "COLMAP's random seed")->capture_default_str();
  cmd->add_option("--ground-truth", o.ground_truth,
                  "survey poses (COLMAP images.txt): report the cameras' error after a "
                  "similarity alignment");
  cmd->add_flag("--no-audit", args->no_audit, "skip the audit (no ID.audit.json)");
  cmd->add_flag("--json", args->json, "print the report as JSON");
  cmd->callback([args] { RunMap(*args); });
}

}  // namespace linecloud
