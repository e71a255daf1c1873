// SIFT features as COLMAP 3.8's CPU extractor computes them
// (`colmap feature_extractor --SiftExtraction.use_gpu 0`): Lowe's detector
// and descriptor (D. G. Lowe, "Distinctive Image Features from Scale-Invariant
// Keypoints", IJCV 2004) as implemented by VLFeat (Vedaldi & Fulkerson, the
// library COLMAP's CPU SIFT is built on), with COLMAP's default options and
// post-processing:
//   - keypoints at VLFeat's position + 0.5 (COLMAP: pixel centres at 0.5);
//   - up to 2 orientations per keypoint (VLFeat's first local maxima);
//   - the finest DoG levels dropped until at most max_num_features
//     keypoints (counted before orientations) remain — whole levels;
//   - descriptors reordered from VLFeat's bin order to the UBC / SiftGPU
//     order, L1-normalised, square-rooted (RootSIFT), scaled by 512, rounded
//     and clamped to bytes.
// The scale space and gradients that VLFeat computes on one scalar thread are
// computed here to the same bits, vectorised and threaded (sift_scale_space.h);
// VLFeat's detector, orientations and descriptors run on them.
// Another extractor, OpenCV's SIFT (Lowe's detector and descriptor, OpenCV
// 4.6 from Debian: SIMD, threaded), gives descriptors in the same layout and
// normalisation (sift_opencv.h); `SiftOptions::extractor` chooses.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "linecloud/features/image.h"

namespace linecloud {

enum class SiftExtractor {
  kColmap,  // COLMAP 3.8's CPU extractor's features, to the bit (VLFeat's, our scale space)
  kOpenCV,  // OpenCV's SIFT, same thresholds and octaves: close, not identical (sift_opencv.h)
};

// "colmap" or "opencv"; throws Error naming `option` otherwise.
SiftExtractor ParseSiftExtractor(const std::string& name, const std::string& option);
const char* SiftExtractorName(SiftExtractor extractor);

struct SiftOptions {
  // colmap: as fast as OpenCV's and the features COLMAP's maps were built
  // with (docs/fast_photo.md).
  SiftExtractor extractor = SiftExtractor::kColmap;
  int max_image_size = 3200;  // larger images are downscaled first
  int max_num_features = 8192;
  int first_octave = -1;
  int num_octaves = 4;
  int octave_resolution = 3;  // DoG levels per octave
  double peak_threshold = 0.02 / 3;
  double edge_threshold = 10.0;
  int max_num_orientations = 2;
  // The colmap extractor's threads (rows of the scale space, keypoints'
  // descriptors); the same features on any count. OpenCV's extractor uses
  // its process-wide pool instead (SetOpenCVThreads).
  int threads = 1;
  // The colmap extractor with VLFeat's own scale space and gradients (one
  // thread, ~2x slower, the same features): the reference of tests and
  // benchmarks (sift_scale_space.h).
  bool vlfeat_scale_space = false;
  // When the caller stops waiting (a service's request): the colmap
  // extractor stops between octaves and between described levels, and its
  // wait for scale-space memory (SetSiftMemoryLimit) ends, with
  // DeadlinePassed. OpenCV's extractor runs to its end.
  std::optional<std::chrono::steady_clock::time_point> deadline;
  // Polled as the deadline is: true stops the extraction (DeadlinePassed),
  // e.g. Python's Ctrl-C. Called on the extracting thread only.
  std::function<bool()> should_stop;

  void Check() const;
};

struct SiftKeypoint {
  float x = 0, y = 0;     // pixels, COLMAP convention (top-left pixel centre at 0.5, 0.5)
  float scale = 0;        // sigma, pixels
  float orientation = 0;  // radians
};

struct SiftFeatures {
  std::vector<SiftKeypoint> keypoints;
  std::vector<uint8_t> descriptors;  // keypoints.size() x 128, UBC bin order
  int image_width = 0, image_height = 0;

  size_t size() const { return keypoints.size(); }
  const uint8_t* descriptor(size_t i) const { return descriptors.data() + 128 * i; }
};

// Features of `image` by `options.extractor`.
SiftFeatures ExtractSift(const GreyImage& image, const SiftOptions& options = {});
// The COLMAP-identical extractor (VLFeat), whatever options.extractor says.
SiftFeatures ExtractSiftColmap(const GreyImage& image, const SiftOptions& options = {});

// The scale-space bytes the colmap extractor maps for a `width` x `height`
// photo (after downscaling to max_image_size; ~320 bytes per pixel at the
// default first octave -1): what it reserves under SetSiftMemoryLimit
// (sift_scale_space.h). The photo's decoding comes on top.
size_t SiftScaleSpaceBytes(int width, int height, const SiftOptions& options = {});

// A SIFT descriptor of any positive scale in UBC bin order (VLFeat's after
// reordering, OpenCV's, Lowe's) to COLMAP's bytes: L1-normalised,
// square-rooted (RootSIFT), x 512, rounded, clamped to [0, 255].
void RootSiftBytes(const float* descriptor, uint8_t* out);

}  // namespace linecloud
