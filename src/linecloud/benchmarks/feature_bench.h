// `linecloud bench features`: our SIFT (features/sift.h) against COLMAP 3.8's
// own CPU extractor (`colmap feature_extractor --SiftExtraction.use_gpu 0`,
// one thread) on the same images: agreement of keypoints and descriptors, and
// time per megapixel of each.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace linecloud {

struct SiftAgreement {
  std::string image;
  int width = 0, height = 0;
  size_t colmap = 0, ours = 0;
  size_t located = 0;     // COLMAP keypoints with one of ours within 0.05 px, same orientation
  size_t identical = 0;   // ... with a byte-identical descriptor
  size_t within_one = 0;  // ... with every byte within ±1
  double ours_ms = 0;     // decode + extract, one thread
  double colmap_ms = 0;   // the whole `colmap feature_extractor` run, one thread
};

// Runs `colmap` (the command, e.g. "colmap") on `image_dir/name` in a scratch
// folder `work_dir`; throws Error when COLMAP fails.
SiftAgreement CompareSiftWithColmap(const std::string& image_dir, const std::string& name,
                                    const std::string& work_dir,
                                    const std::string& colmap = "colmap");

nlohmann::json SiftAgreementToJson(const SiftAgreement& a);

}  // namespace linecloud
