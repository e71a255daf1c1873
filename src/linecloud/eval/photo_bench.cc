#include "linecloud/eval/photo_bench.h"

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <numbers>
#include <random>

#include <fmt/format.h>

#include "linecloud/benchmarks/match_bench.h"
#include "linecloud/colmap/colmap_runner.h"
#include "linecloud/eval/direct_matching.h"
#include "linecloud/eval/eval_run.h"
#include "linecloud/features/sift_opencv.h"
#include "linecloud/pipeline/localizer.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/statistics.h"

namespace linecloud {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

std::vector<std::string> PaddingImages(const std::string& dir, const std::string& dataset_dir) {
  std::vector<std::string> images;
  const std::string skip = fs::weakly_canonical(dataset_dir).string();
  for (std::string& path : PhotosUnder(dir)) {
    if (fs::weakly_canonical(path).string().rfind(skip, 0) == 0) continue;  // the work's scene
    images.push_back(std::move(path));
  }
  return images;
}

// `data` with `padding` descriptors on seeded random lines through its
// points' bounding box (ids above every map id): distractors for matching and
// outliers for RANSAC, as a larger map brings.
void Pad(GroupMapData* data, const std::vector<uint8_t>& padding, size_t count) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(1e300), hi = -lo;
  uint64_t next_id = 0;
  for (const auto& [id, x] : data->points.points) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
    next_id = std::max(next_id, id + 1);
  }
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  for (size_t k = 0; k < count; ++k) {
    const Eigen::Vector3d x = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(u(rng), u(rng), u(rng)));
    const Eigen::Vector3d v(g(rng), g(rng), g(rng));
    const uint64_t id = next_id + k;
    data->lines.lines.emplace(id, PluckerLine::FromPointAndDirection(x, v));
    data->descriptors.ids.push_back(id);
    data->descriptors.descriptors.insert(data->descriptors.descriptors.end(),
                                         padding.begin() + k * 128,
                                         padding.begin() + (k + 1) * 128);
  }
}

// COLMAP's CLI feature extraction of one photo: the whole command, ms.
double ColmapExtractMs(const std::string& colmap, const std::string& image_dir,
                       const std::string& name, int threads, const std::string& scratch) {
  CreateDirectories(scratch);
  const std::string db = JoinPaths(scratch, "features.db");
  std::error_code ec;
  fs::remove(db, ec);
  const std::string list = JoinPaths(scratch, "list.txt");
  WriteFileAtomically(list, [&](std::ostream& os) { os << name << "\n"; });
  ColmapOptions o;
  o.executable = colmap;
  const auto start = std::chrono::steady_clock::now();
  RunColmapCommand({colmap, "feature_extractor", "--database_path", db, "--image_path", image_dir,
                    "--image_list_path", list, "--SiftExtraction.use_gpu", "0",
                    "--SiftExtraction.num_threads", std::to_string(threads)},
                   JoinPaths(scratch, "colmap.log"), o);
  return MsSince(start);
}

struct Samples {
  std::map<std::string, std::vector<double>> ms;  // by stage
  std::vector<double> rotation;
  int localized = 0, photos = 0;
  std::vector<double> features, matches;
};

json Summary(const Samples& s) {
  json stages = json::object();
  for (const auto& [stage, v] : s.ms) {
    stages[stage] = {{"p50", Percentile(v, 50)}, {"p99", Percentile(v, 99)}};
  }
  return {{"photos", s.photos},
          {"localized", s.localized},
          {"median_rotation_deg", Median(s.rotation)},
          {"median_features", Median(s.features)},
          {"median_matches", Median(s.matches)},
          {"ms", stages}};
}

}  // namespace

void PhotoBenchOptions::Check() const {
  if (work_dir.empty()) Fail("bench photo: --work is required");
  if (extractors.empty()) Fail("bench photo: no extractor");
  for (const int t : threads) {
    if (t < 1 || t > 256) Fail("bench photo: threads {} out of range [1, 256]", t);
  }
  if (threads.empty()) Fail("bench photo: no thread count");
  if (max_image_size < 16) Fail("bench photo: --max-image-size must be at least 16");
  if (pad_to > 0 && padding_dir.empty()) Fail("bench photo: padding needs --padding DIR");
}

json RunPhotoBench(const PhotoBenchOptions& o) {
  o.Check();
  const EvalWork work = ReadPreparedWork(o.work_dir);
  const LiftingKey key = EvalLiftingKey(o.work_dir);
  const std::string image_dir = JoinPaths(work.dataset_dir, "images");
  // Every photo of every query group, alone, against its group's map (which
  // holds none of the group's photos).
  std::vector<std::pair<const EvalGroup*, const EvalImage*>> photos;
  for (const EvalGroup& g : work.groups) {
    for (const EvalImage& im : g.images) {
      if (o.max_photos == 0 || photos.size() < o.max_photos) photos.push_back({&g, &im});
    }
  }
  if (photos.empty()) Fail("bench photo: {} has no query photo", o.work_dir);
  const auto say = [&](const std::string& s) {
    if (o.progress) o.progress(s);
  };
  std::vector<uint8_t> padding;
  if (o.pad_to > 0) {
    say(fmt::format("padding descriptors from {}", o.padding_dir));
    padding = PhotoDescriptors(PaddingImages(o.padding_dir, work.dataset_dir), o.pad_to, nullptr);
  }
  const fs::path scratch = fs::temp_directory_path() /
                           fmt::format("linecloud-bench-photo-{}", static_cast<long>(::getpid()));
  CreateDirectories(scratch.string());
  const std::array<uint8_t, 32> cache_key{};  // a scratch cache, deleted below

  // rows[extractor][threads]
  std::map<std::pair<SiftExtractor, int>, Samples> rows;
  std::map<int, std::vector<double>> colmap_ms;
  size_t map_lines = 0, padded_lines = 0;
  for (const auto& [g, photo] : photos) {
    const EvalImage& im = *photo;
    GroupMapData data = LoadGroupMapData(o.work_dir, *g, key, MapLifting{});
    map_lines += data.lines.lines.size();
    if (o.pad_to > data.lines.lines.size()) {
      Pad(&data, padding, o.pad_to - data.lines.lines.size());
    }
    padded_lines += data.lines.lines.size();
    const std::string path = JoinPaths(image_dir, im.name);
    const std::string bytes = ReadFileToString(path);
    const Camera& camera = work.cameras.at(im.camera_id);
    const std::string cache = (scratch / (g->name + "-" + im.name + ".index")).string();
    for (const SiftExtractor e : o.extractors) {
      LocalizerOptions lo;
      lo.image.sift.extractor = e;
      lo.image.sift.max_image_size = o.max_image_size;
      lo.index_cache = cache;  // the second extractor's Localizer loads the first's index
      lo.index_cache_key = cache_key;
      say(fmt::format("{} ({}): {} lines, {} extractor", g->name, im.name, data.lines.lines.size(),
                      SiftExtractorName(e)));
      const Localizer localizer(LocalizationMap(data.lines), data.descriptors, lo, g->name);
      for (const int t : o.threads) {
        SetOpenCVThreads(t);
        LocalizeRequest request;
        request.threads = t;
        const LocalizerResult r = localizer.LocalizeEncodedImage(
            std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size()), camera,
            request, im.name);
        Samples& s = rows[{e, t}];
        ++s.photos;
        const StageTimes& st = r.times;
        s.ms["decode"].push_back(st.decode_ms);
        s.ms["extract"].push_back(st.extract_ms);
        s.ms["match"].push_back(st.match_ms);
        s.ms["ransac_refine"].push_back(st.prepare_ms + st.ransac_ms + st.refine_ms);
        s.ms["checks"].push_back(st.check_ms);
        s.ms["total"].push_back(st.total_ms);
        s.features.push_back(static_cast<double>(r.num_features()));
        s.matches.push_back(static_cast<double>(r.num_matches()));
        double rot = 180;
        if (r.success()) {
          const LocalizationError err =
              CompareLocalization(r.pose.query_from_world, ToSim3(im.cam_from_world));
          rot = err.rotation_rad * 180 / std::numbers::pi;
          s.localized += rot <= o.max_rotation_deg && err.position <= o.max_translation;
        }
        s.rotation.push_back(rot);
      }
    }
    if (!o.colmap.empty()) {
      for (const int t : o.threads) {
        colmap_ms[t].push_back(
            ColmapExtractMs(o.colmap, image_dir, im.name, t, (scratch / "colmap").string()));
      }
    }
  }
  std::error_code ec;
  fs::remove_all(scratch, ec);

  json out = {{"work", o.work_dir},
              {"max_image_size", o.max_image_size},
              {"dataset", work.dataset},
              {"photos", photos.size()},
              {"mean_map_lines", map_lines / photos.size()},
              {"mean_padded_lines", padded_lines / photos.size()},
              {"rows", json::array()}};
  for (const auto& [config, s] : rows) {
    json row = Summary(s);
    row["features"] = SiftExtractorName(config.first);
    row["threads"] = config.second;
    out["rows"].push_back(row);
  }
  json peers = json::object();
  for (const auto& [t, v] : colmap_ms) {
    peers[std::to_string(t)] = {{"p50", Percentile(v, 50)}, {"p99", Percentile(v, 99)}};
  }
  out["colmap_cli_extract_ms"] = peers;
  return out;
}

std::string PhotoBenchMarkdown(const json& report) {
  std::string md = fmt::format(
      "bench photo: {} photos of {}, JPEG bytes to pose (SIFT on at most {} px); maps of {} lines "
      "padded to {}\n\n"
      "| features | threads | localized | median rot. ° | features | matches | decode | extract "
      "p50 / p99 | match p50 / p99 | RANSAC+LM | checks | total p50 / p99 ms |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n",
      report["photos"].get<size_t>(), report["dataset"].get<std::string>(),
      report["max_image_size"].get<int>(), report["mean_map_lines"].get<size_t>(),
      report["mean_padded_lines"].get<size_t>());
  for (const json& r : report["rows"]) {
    const json& ms = r["ms"];
    auto p = [&](const char* stage, const char* which) { return ms[stage][which].get<double>(); };
    md += fmt::format(
        "| {} | {} | {} / {} | {:.4f} | {:.0f} | {:.0f} | {:.0f} | {:.0f} / {:.0f} | {:.0f} / "
        "{:.0f} | {:.0f} | {:.0f} | **{:.0f}** / {:.0f} |\n",
        r["features"].get<std::string>(), r["threads"].get<int>(), r["localized"].get<int>(),
        r["photos"].get<int>(), r["median_rotation_deg"].get<double>(),
        r["median_features"].get<double>(), r["median_matches"].get<double>(), p("decode", "p50"),
        p("extract", "p50"), p("extract", "p99"), p("match", "p50"), p("match", "p99"),
        p("ransac_refine", "p50"), p("checks", "p50"), p("total", "p50"), p("total", "p99"));
  }
  for (const auto& [t, v] : report["colmap_cli_extract_ms"].items()) {
    md += fmt::format(
        "| COLMAP CLI `feature_extractor` (whole command) | {} | | | | | | {:.0f} / {:.0f} | | | "
        "| |\n",
        t, v["p50"].get<double>(), v["p99"].get<double>());
  }
  return md;
}

}  // namespace linecloud
