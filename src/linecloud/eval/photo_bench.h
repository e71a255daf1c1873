// `linecloud bench photo`: a photo to a pose the way a service answers it —
// JPEG bytes → decode → SIFT → matching → RANSAC → LM → checks, through the
// Localizer — on an `eval prepare` work's query photos, each against
// its group's line map (built without that photo) padded with the descriptors
// of other scenes' photos on random lines to a realistic size (100 000 lines:
// [fast-photo]'s target); every photo of a query group alone. Each extractor and thread count in
// one run, with COLMAP's own command-line extraction of the same photos beside them; per stage p50
// / p99, photos localized and their median rotation error.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "linecloud/features/sift.h"

namespace linecloud {

struct PhotoBenchOptions {
  std::string work_dir;    // of `eval prepare`
  size_t pad_to = 100000;  // lines per map after padding (0: no padding)
  // Photos whose descriptors pad the maps (other scenes): JPEG / PNG files
  // under this folder outside the work's dataset.
  std::string padding_dir;
  std::vector<SiftExtractor> extractors = {SiftExtractor::kColmap, SiftExtractor::kOpenCV};
  std::vector<int> threads = {1, 2};
  int max_image_size = 3200;      // photos with a larger side are downscaled first (SIFT)
  size_t max_photos = 0;          // 0: every query photo of the work
  std::string colmap = "colmap";  // COLMAP's CLI as a peer; empty: not run
  double max_rotation_deg = 0.5;  // "localized" thresholds, as eval's direct matching
  double max_translation = 0.05;
  std::function<void(const std::string&)> progress;

  void Check() const;
};

// A stage's time over the photos (ms).
struct Quantiles {
  double p50 = 0, p99 = 0;
};

struct PhotoStageTimes {
  Quantiles decode, extract, match, ransac_refine, checks, total;
};

// One extractor at one thread count, over every photo.
struct PhotoBenchRow {
  std::string features;  // the extractor's name
  int threads = 0;
  int photos = 0, localized = 0;
  double median_rotation_deg = 0, median_features = 0, median_matches = 0;
  PhotoStageTimes ms;
};

struct PhotoBenchReport {
  std::string work, dataset;
  int max_image_size = 0;
  size_t photos = 0, mean_map_lines = 0, mean_padded_lines = 0;
  std::vector<PhotoBenchRow> rows;
  std::map<int, Quantiles> colmap_cli_extract_ms;  // by thread count (COLMAP's whole command)
};

PhotoBenchReport RunPhotoBench(const PhotoBenchOptions& options);

// The report as JSON (`bench photo --json`) and as a Markdown table.
nlohmann::json ToJson(const PhotoBenchReport& report);
std::string PhotoBenchMarkdown(const PhotoBenchReport& report);

}  // namespace linecloud
