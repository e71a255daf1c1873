// Structure from motion by COLMAP's command line (Debian package `colmap`,
// CPU only) with the dataset's known intrinsics held fixed. Results are
// cached: a run is skipped when a fingerprint of its inputs (COLMAP's
// version, cameras, image files, options) matches the one stored with it.
#pragma once

#include <string>
#include <vector>

#include "linecloud/colmap/dataset.h"
#include "linecloud/io/colmap_model.h"

namespace linecloud {

struct ColmapOptions {
  std::string executable = "colmap";
  int num_threads = -1;       // COLMAP's default: all cores
  int max_image_size = 3200;  // SiftExtraction.max_image_size (COLMAP's default)
  // Affine-covariant SIFT with domain-size pooling and guided matching
  // (slower; more accurate keypoints).
  bool accurate_features = false;
  bool verbose = false;  // stream COLMAP's output instead of logging it to files

  void Check() const;
};

// Runs `args` (argv[0] = COLMAP executable); output goes to `log_path`.
// Throws Error quoting the log's last lines when the command fails.
void RunColmapCommand(const std::vector<std::string>& args, const std::string& log_path,
                      const ColmapOptions& options);

// Feature extraction (one pass per camera, its intrinsics fixed), exhaustive
// matching and mapping of all images into `colmap_dir` (database.db,
// sparse/<k>/). Returns the model with the most registered images. Prints
// progress; reuses a cached result whose fingerprint matches.
Reconstruction ReconstructDataset(const EvalDataset& dataset, const std::string& colmap_dir,
                                  const ColmapOptions& options);

// Maps only `image_names` (features and matches from `database_path`) into
// `out_dir`; the local reconstruction of a query group (its scale is
// arbitrary). Returns the model with the most registered images, or an empty
// Reconstruction when COLMAP could not initialise one. Cached like above.
Reconstruction ReconstructImageSubset(const std::string& database_path,
                                      const std::string& image_dir,
                                      const std::vector<std::string>& image_names,
                                      const std::string& out_dir, const ColmapOptions& options);

}  // namespace linecloud
