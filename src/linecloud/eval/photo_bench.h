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

nlohmann::json RunPhotoBench(const PhotoBenchOptions& options);

// The rows as a Markdown table.
std::string PhotoBenchMarkdown(const nlohmann::json& report);

}  // namespace linecloud
