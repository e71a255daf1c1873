#include "linecloud/features/sift.h"

extern "C" {
#include <vl/sift.h>
}

#include <algorithm>
#include <array>
#include <cmath>

#include "linecloud/features/sift_opencv.h"
#include "linecloud/features/sift_scale_space.h"
#include "linecloud/util/error.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

// VLFeat orders the 8 orientation bins of each spatial cell the other way
// round from Lowe's / SiftGPU's (UBC) layout: bin k goes to (8 − k) mod 8.
void VlFeatToUbc(const float* in, float* out) {
  for (int cell = 0; cell < 16; ++cell) {
    for (int k = 0; k < 8; ++k) out[8 * cell + (8 - k) % 8] = in[8 * cell + k];
  }
}

// A keypoint's orientations (VLFeat's first local maxima, at most the
// options' count) and a descriptor in COLMAP's bytes for each.
struct Oriented {
  int count = 0;
  double angles[4] = {};
  std::array<std::array<uint8_t, 128>, 4> descriptors;
};

// Reads the filter only once its gradients are up to date: any thread.
// `own`: our descriptor (DescribeKeypoint, the same bits) instead of VLFeat's.
void Orient(VlSiftFilt* f, const VlSiftKeypoint& k, int max_orientations, bool own, Oriented* out) {
  const int found = vl_sift_calc_keypoint_orientations(f, out->angles, &k);
  out->count = std::min(found, max_orientations);
  std::array<float, 128> raw, ubc;
  for (int o = 0; o < out->count; ++o) {
    if (own) {
      DescribeKeypoint(f, k, out->angles[o], raw.data());
    } else {
      vl_sift_calc_keypoint_descriptor(f, raw.data(), &k, out->angles[o]);
    }
    VlFeatToUbc(raw.data(), ubc.data());
    RootSiftBytes(ubc.data(), out->descriptors[o].data());
  }
}

// The keypoints VLFeat detected on one DoG level (one octave's, in its order),
// and once described, the features they give.
struct Level {
  int octave = 0;  // index into the octaves processed
  std::vector<VlSiftKeypoint> detected;
  std::vector<SiftKeypoint> keypoints;
  std::vector<uint8_t> descriptors;
};

// Where a described octave's gradients are, to describe its keypoints later.
struct OctaveGradients {
  int o = 0, width = 0, height = 0;
  float* gradients = nullptr;
};

// The current octave's detections appended, one Level per run of keypoints
// on the same DoG level.
void AppendLevels(const VlSiftFilt* f, int octave, std::vector<Level>* levels) {
  const VlSiftKeypoint* keypoints = vl_sift_get_keypoints(const_cast<VlSiftFilt*>(f));
  const int n = vl_sift_get_nkeypoints(const_cast<VlSiftFilt*>(f));
  int previous = -1;
  for (int i = 0; i < n; ++i) {
    if (keypoints[i].is != previous || i == 0) {
      levels->emplace_back();
      levels->back().octave = octave;
    }
    previous = keypoints[i].is;
    levels->back().detected.push_back(keypoints[i]);
  }
}

// COLMAP's cap: the coarsest levels kept while the detections (before
// orientations) stay within `max_features`; the level crossing it is kept
// whole. Returns the index of the finest level kept.
size_t FirstKeptLevel(const std::vector<Level>& levels, int max_features) {
  size_t detections = 0;
  for (size_t i = levels.size(); i-- > 0;) {
    detections += levels[i].detected.size();
    if (detections > static_cast<size_t>(max_features)) return i;
  }
  return 0;
}

// Orientations and descriptors of a level's keypoints, the filter set to its
// octave (on `threads` threads: the gradients are computed already).
void DescribeLevel(VlSiftFilt* f, const SiftOptions& options, bool own, int threads, float scale_x,
                   float scale_y, Level* level) {
  const std::vector<VlSiftKeypoint>& detected = level->detected;
  std::vector<Oriented> oriented(detected.size());
  ParallelFor(detected.size(), threads, [&](size_t i, int) {
    Orient(f, detected[i], options.max_num_orientations, own, &oriented[i]);
  });
  for (size_t i = 0; i < detected.size(); ++i) {
    const VlSiftKeypoint& k = detected[i];
    for (int j = 0; j < oriented[i].count; ++j) {
      level->keypoints.push_back({(k.x + 0.5f) * scale_x, (k.y + 0.5f) * scale_y, k.sigma * scale_x,
                                  static_cast<float>(oriented[i].angles[j])});
      level->descriptors.insert(level->descriptors.end(), oriented[i].descriptors[j].begin(),
                                oriented[i].descriptors[j].end());
    }
  }
}

}  // namespace

void RootSiftBytes(const float* v, uint8_t* out) {
  float l1 = 0;
  for (int i = 0; i < 128; ++i) l1 += std::abs(v[i]);
  for (int i = 0; i < 128; ++i) {
    const float normalized = l1 > 0 ? std::sqrt(std::abs(v[i]) / l1) : 0.0f;
    const float scaled = std::round(512.0f * normalized);
    out[i] = static_cast<uint8_t>(std::clamp(scaled, 0.0f, 255.0f));
  }
}

SiftExtractor ParseSiftExtractor(const std::string& name, const std::string& option) {
  if (name == "colmap") return SiftExtractor::kColmap;
  if (name == "opencv") return SiftExtractor::kOpenCV;
  Fail("{}: unknown feature extractor '{}' (colmap or opencv)", option, name);
}

const char* SiftExtractorName(SiftExtractor extractor) {
  return extractor == SiftExtractor::kColmap ? "colmap" : "opencv";
}

SiftFeatures ExtractSift(const GreyImage& image, const SiftOptions& options) {
  return options.extractor == SiftExtractor::kColmap ? ExtractSiftColmap(image, options)
                                                     : ExtractSiftOpenCV(image, options);
}

void SiftOptions::Check() const {
  if (max_image_size <= 0) Fail("SIFT max_image_size must be positive, got {}", max_image_size);
  if (max_num_features <= 0)
    Fail("SIFT max_num_features must be positive, got {}", max_num_features);
  if (num_octaves <= 0 || octave_resolution <= 0) {
    Fail("SIFT octaves ({}) and octave resolution ({}) must be positive", num_octaves,
         octave_resolution);
  }
  if (!(peak_threshold > 0) || !(edge_threshold > 0)) {
    Fail("SIFT peak ({}) and edge ({}) thresholds must be positive", peak_threshold,
         edge_threshold);
  }
  if (max_num_orientations < 1 || max_num_orientations > 4) {
    Fail("SIFT max_num_orientations must be 1 to 4, got {}", max_num_orientations);
  }
  if (threads < 1) Fail("SIFT threads must be at least 1, got {}", threads);
}

size_t SiftScaleSpaceBytes(int width, int height, const SiftOptions& options) {
  options.Check();
  const auto [w, h] = DownscaledSize(width, height, options.max_image_size);
  return SiftFilterBytes(w, h, options.num_octaves, options.octave_resolution,
                         options.first_octave);
}

SiftFeatures ExtractSiftColmap(const GreyImage& input, const SiftOptions& options) {
  options.Check();
  if (input.width < 8 || input.height < 8) {
    Fail("image of {}x{} pixels is too small for SIFT", input.width, input.height);
  }
  const GreyImage image = DownscaleToMaxSize(input, options.max_image_size);
  const float scale_x = static_cast<float>(input.width) / image.width;
  const float scale_y = static_cast<float>(input.height) / image.height;

  // The last octave must keep 2 x 2 pixels (VLFeat's gradients and ours need a neighbour).
  const int last_octave = options.first_octave + options.num_octaves - 1;
  if (last_octave >= 30 ||
      (last_octave > 0 && (std::min(image.width, image.height) >> last_octave) < 2)) {
    Fail("image of {}x{} pixels is too small for {} SIFT octaves", image.width, image.height,
         options.num_octaves);
  }
  // VLFeat's own scale space (the reference, and first octaves below -1,
  // sift_scale_space.h) computes the gradients lazily into one buffer inside
  // the first orientation call: one thread, each octave described at once.
  // Ours keeps each octave's gradients, so that only the levels the cap keeps
  // are described (a third of the Strecha photos' detections are on the
  // finest level, which the cap drops).
  const bool own = !options.vlfeat_scale_space && options.first_octave >= -1;
  SiftFilter sift(image.width, image.height, options.num_octaves, options.octave_resolution,
                  options.first_octave, /*vlfeat_gradients=*/!own,
                  SiftDeadline(options.deadline, options.should_stop));
  VlSiftFilt* f = sift.get();
  vl_sift_set_peak_thresh(f, options.peak_threshold);
  vl_sift_set_edge_thresh(f, options.edge_threshold);

  std::vector<float> pixels(image.pixels.size());
  for (size_t i = 0; i < pixels.size(); ++i) pixels[i] = image.pixels[i] / 255.0f;

  const int threads = own ? options.threads : 1;
  std::vector<Level> levels;
  std::vector<OctaveGradients> octaves;
  const SiftDeadline until(options.deadline, options.should_stop);
  for (bool more = own ? ProcessFirstOctave(f, pixels.data(), threads, until)
                       : vl_sift_process_first_octave(f, pixels.data()) != VL_ERR_EOF;
       more; more = own ? ProcessNextOctave(f, threads, until)
                        : vl_sift_process_next_octave(f) != VL_ERR_EOF) {
    StopAtSiftDeadline(until);
    vl_sift_detect(f);
    const size_t first_new = levels.size();
    AppendLevels(f, static_cast<int>(octaves.size()), &levels);
    if (own) {
      const size_t pixels_here = static_cast<size_t>(f->octave_width) * f->octave_height;
      f->grad = sift.Allocate(2 * (f->s_max - f->s_min - 2) * pixels_here);
      f->grad_o = f->o_min - 1;  // not computed yet
      StopAtSiftDeadline(until);
      UpdateGradients(f, threads);
      octaves.push_back({f->o_cur, f->octave_width, f->octave_height, f->grad});
    } else {
      for (size_t i = first_new; i < levels.size(); ++i)
        DescribeLevel(f, options, false, 1, scale_x, scale_y, &levels[i]);
    }
  }
  const size_t first_kept = FirstKeptLevel(levels, options.max_num_features);
  if (own) {
    for (size_t i = first_kept; i < levels.size(); ++i) {
      StopAtSiftDeadline(until);
      const OctaveGradients& octave = octaves[levels[i].octave];
      f->o_cur = f->grad_o = octave.o;
      f->octave_width = octave.width;
      f->octave_height = octave.height;
      f->grad = octave.gradients;
      DescribeLevel(f, options, true, threads, scale_x, scale_y, &levels[i]);
    }
  }

  SiftFeatures features;
  features.image_width = input.width;
  features.image_height = input.height;
  for (size_t i = first_kept; i < levels.size(); ++i) {
    features.keypoints.insert(features.keypoints.end(), levels[i].keypoints.begin(),
                              levels[i].keypoints.end());
    features.descriptors.insert(features.descriptors.end(), levels[i].descriptors.begin(),
                                levels[i].descriptors.end());
  }
  return features;
}

}  // namespace linecloud
