#include "linecloud/features/sift_opencv.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <functional>
#include <map>
#include <set>
#include <tuple>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// OpenCV packs the octave into the low byte of KeyPoint::octave, signed.
int KeypointOctave(const cv::KeyPoint& k) {
  const int octave = k.octave & 255;
  return octave < 128 ? octave : octave - 256;
}

}  // namespace

void SetOpenCVThreads(int threads) {
  if (threads < 1) Fail("threads must be at least 1, got {}", threads);
  cv::setNumThreads(threads);
}

int OpenCVThreads() { return cv::getNumThreads(); }

SiftFeatures ExtractSiftOpenCV(const GreyImage& input, const SiftOptions& options) {
  options.Check();
  if (options.first_octave != -1) {
    Fail("the OpenCV extractor starts at octave -1 (the image doubled), got first_octave {}",
         options.first_octave);
  }
  if (input.width < 8 || input.height < 8) {
    Fail("image of {}x{} pixels is too small for SIFT", input.width, input.height);
  }
  const GreyImage image = DownscaleToMaxSize(input, options.max_image_size);
  const float scale_x = static_cast<float>(input.width) / image.width;
  const float scale_y = static_cast<float>(input.height) / image.height;

  // OpenCV does not write through the header's pointer.
  const cv::Mat mat(image.height, image.width, CV_8UC1, const_cast<uint8_t*>(image.pixels.data()));
  cv::Ptr<cv::SIFT> sift = cv::SIFT::create(0, options.octave_resolution,
                                            options.peak_threshold * options.octave_resolution,
                                            options.edge_threshold, 1.6, CV_32F);
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  sift->detectAndCompute(mat, cv::noArray(), keypoints, descriptors);

  // COLMAP's rule: whole DoG levels from the coarsest down while the
  // detections (keypoints before orientations) stay within max_num_features;
  // the level that crosses it is kept whole. Only COLMAP's octaves.
  const int last_octave = options.first_octave + options.num_octaves - 1;
  std::map<std::pair<int, int>, std::vector<int>, std::greater<>> levels;  // coarsest first
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const int octave = KeypointOctave(keypoints[i]);
    if (octave > last_octave) continue;
    levels[{octave, (keypoints[i].octave >> 8) & 255}].push_back(static_cast<int>(i));
  }
  std::vector<int> order;
  size_t detections = 0;
  for (const auto& [level, members] : levels) {
    std::set<std::pair<float, float>> positions;  // extra orientations share a position
    for (const int i : members) positions.insert({keypoints[i].pt.x, keypoints[i].pt.y});
    order.insert(order.end(), members.begin(), members.end());
    detections += positions.size();
    if (detections > static_cast<size_t>(options.max_num_features)) break;
  }
  // A fixed order, whatever the thread count.
  auto key = [&](int i) {
    const cv::KeyPoint& k = keypoints[i];
    return std::make_tuple(-k.response, k.pt.y, k.pt.x, k.size, k.angle);
  };
  std::sort(order.begin(), order.end(), [&](int a, int b) { return key(a) < key(b); });

  SiftFeatures features;
  features.image_width = input.width;
  features.image_height = input.height;
  features.keypoints.reserve(order.size());
  features.descriptors.resize(order.size() * 128);
  constexpr float kDegrees = std::numbers::pi_v<float> / 180.0f;
  for (size_t n = 0; n < order.size(); ++n) {
    const cv::KeyPoint& k = keypoints[order[n]];
    // OpenCV's angle is 360° less the gradient direction in y-up axes: the
    // direction in y-down image axes, as VLFeat's.
    float angle = std::fmod(k.angle * kDegrees, 2 * std::numbers::pi_v<float>);
    if (angle < 0) angle += 2 * std::numbers::pi_v<float>;
    // OpenCV 4.6 doubles the image with cv::resize (pixel centres aligned),
    // then reads positions at half the doubled grid: 0.25 px right and down
    // of where they are; COLMAP's centres are at +0.5.
    features.keypoints.push_back(
        {(k.pt.x + 0.25f) * scale_x, (k.pt.y + 0.25f) * scale_y, 0.5f * k.size * scale_x, angle});
    RootSiftBytes(descriptors.ptr<float>(order[n]), features.descriptors.data() + 128 * n);
  }
  return features;
}

}  // namespace linecloud
