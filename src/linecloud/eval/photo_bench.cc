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
  std::vector<double> decode, extract, match, ransac_refine, checks, total;  // ms
  std::vector<double> rotation;
  int localized = 0, photos = 0;
  std::vector<double> features, matches;
};

Quantiles Of(const std::vector<double>& v) { return {Percentile(v, 50), Percentile(v, 99)}; }

PhotoBenchRow Summary(const Samples& s) {
  PhotoBenchRow row;
  row.photos = s.photos;
  row.localized = s.localized;
  row.median_rotation_deg = Median(s.rotation);
  row.median_features = Median(s.features);
  row.median_matches = Median(s.matches);
  row.ms = {Of(s.decode),        Of(s.extract), Of(s.match),
            Of(s.ransac_refine), Of(s.checks),  Of(s.total)};
  return row;
}

json ToJson(const Quantiles& q) { return {{"p50", q.p50}, {"p99", q.p99}}; }

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

PhotoBenchReport RunPhotoBench(const PhotoBenchOptions& o) {
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
        s.decode.push_back(st.decode_ms);
        s.extract.push_back(st.extract_ms);
        s.match.push_back(st.match_ms);
        s.ransac_refine.push_back(st.prepare_ms + st.ransac_ms + st.refine_ms);
        s.checks.push_back(st.check_ms);
        s.total.push_back(st.total_ms);
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

  PhotoBenchReport out;
  out.work = o.work_dir;
  out.dataset = work.dataset;
  out.max_image_size = o.max_image_size;
  out.photos = photos.size();
  out.mean_map_lines = map_lines / photos.size();
  out.mean_padded_lines = padded_lines / photos.size();
  for (const auto& [config, s] : rows) {
    PhotoBenchRow& row = out.rows.emplace_back(Summary(s));
    row.features = SiftExtractorName(config.first);
    row.threads = config.second;
  }
  for (const auto& [t, v] : colmap_ms) out.colmap_cli_extract_ms[t] = Of(v);
  return out;
}

json ToJson(const PhotoBenchReport& r) {
  json rows = json::array();
  for (const PhotoBenchRow& row : r.rows) {
    rows.push_back({{"features", row.features},
                    {"threads", row.threads},
                    {"photos", row.photos},
                    {"localized", row.localized},
                    {"median_rotation_deg", row.median_rotation_deg},
                    {"median_features", row.median_features},
                    {"median_matches", row.median_matches},
                    {"ms",
                     {{"decode", ToJson(row.ms.decode)},
                      {"extract", ToJson(row.ms.extract)},
                      {"match", ToJson(row.ms.match)},
                      {"ransac_refine", ToJson(row.ms.ransac_refine)},
                      {"checks", ToJson(row.ms.checks)},
                      {"total", ToJson(row.ms.total)}}}});
  }
  json peers = json::object();
  for (const auto& [t, q] : r.colmap_cli_extract_ms) peers[std::to_string(t)] = ToJson(q);
  return {{"work", r.work},
          {"max_image_size", r.max_image_size},
          {"dataset", r.dataset},
          {"photos", r.photos},
          {"mean_map_lines", r.mean_map_lines},
          {"mean_padded_lines", r.mean_padded_lines},
          {"rows", rows},
          {"colmap_cli_extract_ms", peers}};
}

std::string PhotoBenchMarkdown(const PhotoBenchReport& report) {
  std::string md = fmt::format(
      "bench photo: {} photos of {}, JPEG bytes to pose (SIFT on at most {} px); maps of {} lines "
      "padded to {}\n\n"
      "| features | threads | localized | median rot. ° | features | matches | decode | extract "
      "p50 / p99 | match p50 / p99 | RANSAC+LM | checks | total p50 / p99 ms |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n",
      report.photos, report.dataset, report.max_image_size, report.mean_map_lines,
      report.mean_padded_lines);
  for (const PhotoBenchRow& r : report.rows) {
    const PhotoStageTimes& ms = r.ms;
    md += fmt::format(
        "| {} | {} | {} / {} | {:.4f} | {:.0f} | {:.0f} | {:.0f} | {:.0f} / {:.0f} | {:.0f} / "
        "{:.0f} | {:.0f} | {:.0f} | **{:.0f}** / {:.0f} |\n",
        r.features, r.threads, r.localized, r.photos, r.median_rotation_deg, r.median_features,
        r.median_matches, ms.decode.p50, ms.extract.p50, ms.extract.p99, ms.match.p50, ms.match.p99,
        ms.ransac_refine.p50, ms.checks.p50, ms.total.p50, ms.total.p99);
  }
  for (const auto& [t, q] : report.colmap_cli_extract_ms) {
    md += fmt::format(
        "| COLMAP CLI `feature_extractor` (whole command) | {} | | | | | | {:.0f} / {:.0f} | | | "
        "| |\n",
        t, q.p50, q.p99);
  }
  return md;
}

}  // namespace linecloud
