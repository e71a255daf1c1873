#include "linecloud/features/sift_opencv.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <numbers>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/features/image.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::DataPath;

double Cosine(const uint8_t* a, const uint8_t* b) {
  double ab = 0, aa = 0, bb = 0;
  for (int i = 0; i < 128; ++i) {
    ab += double(a[i]) * b[i];
    aa += double(a[i]) * a[i];
    bb += double(b[i]) * b[i];
  }
  return ab / std::sqrt(aa * bb);
}

double AngleDifference(double a, double b) {
  const double d = std::fmod(std::abs(a - b), 2 * std::numbers::pi);
  return std::min(d, 2 * std::numbers::pi - d);
}

// The two extractors find the same keypoints (position, scale, orientation)
// and describe them alike: OpenCV's descriptor layout and normalisation are
// carried over to COLMAP's correctly (a wrong bin order would give cosines
// near 0.7, a wrong orientation convention angles far apart).
TEST(SiftOpenCV, AgreesWithTheColmapExtractorWhereBothFindAKeypoint) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  const GreyImage image = ReadGreyImage(DataPath("strecha/fountain-P11/images/0000.jpg"));
  const SiftFeatures colmap = ExtractSiftColmap(image);
  const SiftFeatures opencv = ExtractSiftOpenCV(image);
  ASSERT_GT(colmap.size(), 5000u);
  ASSERT_GT(opencv.size(), 5000u);
  // For each OpenCV keypoint, a COLMAP keypoint within 0.3 px, 5 % in scale
  // and 5° in orientation (grid search over a coarse bucket of positions).
  std::vector<std::vector<int>> grid((image.width / 4 + 2) * (image.height / 4 + 2));
  const int gw = image.width / 4 + 2;
  for (size_t i = 0; i < colmap.size(); ++i) {
    const SiftKeypoint& k = colmap.keypoints[i];
    grid[int(k.y / 4) * gw + int(k.x / 4)].push_back(int(i));
  }
  std::vector<double> cosines;
  for (size_t j = 0; j < opencv.size(); ++j) {
    const SiftKeypoint& k = opencv.keypoints[j];
    int best = -1;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const int cell = (int(k.y / 4) + dy) * gw + int(k.x / 4) + dx;
        if (cell < 0 || cell >= int(grid.size())) continue;
        for (int i : grid[cell]) {
          const SiftKeypoint& c = colmap.keypoints[i];
          if (std::hypot(c.x - k.x, c.y - k.y) < 0.3 && std::abs(c.scale / k.scale - 1) < 0.05 &&
              AngleDifference(c.orientation, k.orientation) < 5 * std::numbers::pi / 180) {
            best = i;
          }
        }
      }
    }
    if (best >= 0) cosines.push_back(Cosine(colmap.descriptor(best), opencv.descriptor(j)));
  }
  std::sort(cosines.begin(), cosines.end());
  const double median = cosines.empty() ? 0 : cosines[cosines.size() / 2];
  std::cout << "[ OpenCV vs COLMAP SIFT, fountain-P11/0000.jpg ] COLMAP " << colmap.size()
            << ", OpenCV " << opencv.size() << ", same keypoint " << cosines.size()
            << ", median descriptor cosine " << median << "\n";
  EXPECT_GT(cosines.size(), opencv.size() / 3);
  EXPECT_GT(median, 0.97);
}

TEST(SiftOpenCV, GivesTheSameFeaturesOnOneAndTwoThreads) {
  GreyImage image{320, 240, std::vector<uint8_t>(320 * 240), {}};
  for (int y = 0; y < 240; ++y) {
    for (int x = 0; x < 320; ++x) {
      image.pixels[y * 320 + x] = static_cast<uint8_t>(
          127 + 60 * std::sin(x * 0.21) * std::cos(y * 0.17) + 40 * std::sin((x + 2 * y) * 0.05));
    }
  }
  const int before = OpenCVThreads();
  SetOpenCVThreads(1);
  const SiftFeatures one = ExtractSiftOpenCV(image);
  SetOpenCVThreads(2);
  const SiftFeatures two = ExtractSiftOpenCV(image);
  SetOpenCVThreads(std::max(before, 1));
  ASSERT_GT(one.size(), 20u);
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(one.descriptors, two.descriptors);
  for (size_t i = 0; i < one.size(); ++i) {
    EXPECT_EQ(one.keypoints[i].x, two.keypoints[i].x);
    EXPECT_EQ(one.keypoints[i].y, two.keypoints[i].y);
  }
}

TEST(SiftOpenCV, RefusesOptionsItCannotHonour) {
  GreyImage image{64, 64, std::vector<uint8_t>(64 * 64, 100), {}};
  SiftOptions options;
  options.first_octave = 0;
  EXPECT_THROW(ExtractSiftOpenCV(image, options), Error);
  EXPECT_THROW(ParseSiftExtractor("vlfeat", "--features"), Error);
  EXPECT_EQ(ParseSiftExtractor("colmap", "--features"), SiftExtractor::kColmap);
}

}  // namespace
}  // namespace linecloud
