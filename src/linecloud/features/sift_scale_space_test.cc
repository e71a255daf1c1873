#include "linecloud/features/sift_scale_space.h"

extern "C" {
#include <vl/sift.h>
}

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::DataPath;
using Filter = std::unique_ptr<VlSiftFilt, void (*)(VlSiftFilt*)>;

Filter NewFilter(int width, int height, int first_octave) {
  return Filter(vl_sift_new(width, height, 4, 3, first_octave), vl_sift_delete);
}

// A textured image with values in [0, 1]: smooth shapes, edges and noise.
std::vector<float> TestImage(int width, int height, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> noise(0.0f, 0.2f);
  std::vector<float> image(static_cast<size_t>(width) * height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const float blob = 0.4f * std::sin(0.07f * x) * std::cos(0.05f * y);
      const float edge = ((x / 17 + y / 23) % 2) ? 0.3f : 0.0f;
      image[static_cast<size_t>(y) * width + x] = 0.3f + blob + edge + noise(rng);
    }
  }
  return image;
}

size_t OctaveFloats(const VlSiftFilt* f) {
  return static_cast<size_t>(f->octave_width) * f->octave_height * (f->s_max - f->s_min + 1);
}
size_t GradientFloats(const VlSiftFilt* f) {
  return static_cast<size_t>(2) * f->octave_width * f->octave_height * (f->s_max - f->s_min - 2);
}

// Counts the floats of two buffers whose bits differ.
size_t BitsDiffer(const float* a, const float* b, size_t n) {
  size_t differ = 0;
  for (size_t i = 0; i < n; ++i) differ += std::memcmp(a + i, b + i, sizeof(float)) != 0;
  return differ;
}

// Every level of every octave and every gradient image equal VLFeat's to the
// bit, for each first octave COLMAP could be set to and on 1 or 3 threads.
void ExpectVlFeatsScaleSpace(int width, int height, int first_octave, int threads) {
  SCOPED_TRACE(::testing::Message() << width << "x" << height << ", first octave " << first_octave
                                    << ", " << threads << " threads");
  const std::vector<float> image = TestImage(width, height, 7);
  Filter ours = NewFilter(width, height, first_octave);
  Filter theirs = NewFilter(width, height, first_octave);
  bool more_ours = ProcessFirstOctave(ours.get(), image.data(), threads);
  bool more_theirs = vl_sift_process_first_octave(theirs.get(), image.data()) != VL_ERR_EOF;
  int octaves = 0;
  size_t total_described = 0;
  while (more_ours && more_theirs) {
    ++octaves;
    VlSiftFilt* a = ours.get();
    VlSiftFilt* b = theirs.get();
    ASSERT_EQ(a->octave_width, b->octave_width);
    ASSERT_EQ(a->octave_height, b->octave_height);
    EXPECT_EQ(BitsDiffer(a->octave, b->octave, OctaveFloats(a)), 0u) << "octave " << a->o_cur;
    // VLFeat updates its gradients on the first orientation call of an octave.
    VlSiftKeypoint corner{};
    corner.o = b->o_cur;
    corner.is = b->s_min + 1;
    corner.sigma = static_cast<float>(std::pow(2.0, b->o_cur));
    double angles[4];
    vl_sift_calc_keypoint_orientations(b, angles, &corner);
    ASSERT_EQ(b->grad_o, b->o_cur);
    UpdateGradients(a, threads);
    EXPECT_EQ(a->grad_o, a->o_cur);
    EXPECT_EQ(BitsDiffer(a->grad, b->grad, GradientFloats(a)), 0u) << "octave " << a->o_cur;
    // Every detected keypoint's descriptors, raw floats, at each orientation.
    vl_sift_detect(b);
    size_t described = 0, descriptors_differ = 0;
    for (int i = 0; i < vl_sift_get_nkeypoints(b); ++i) {
      const VlSiftKeypoint& k = vl_sift_get_keypoints(b)[i];
      const int found = vl_sift_calc_keypoint_orientations(b, angles, &k);
      for (int o = 0; o < found; ++o) {
        float theirs_d[128], ours_d[128];
        vl_sift_calc_keypoint_descriptor(b, theirs_d, &k, angles[o]);
        DescribeKeypoint(a, k, angles[o], ours_d);
        descriptors_differ += BitsDiffer(ours_d, theirs_d, 128) != 0;
        ++described;
      }
    }
    total_described += described;
    EXPECT_EQ(descriptors_differ, 0u) << "octave " << a->o_cur << ", of " << described;
    more_ours = ProcessNextOctave(a, threads);
    more_theirs = vl_sift_process_next_octave(b) != VL_ERR_EOF;
  }
  EXPECT_EQ(more_ours, more_theirs);
  EXPECT_EQ(octaves, 4);
  EXPECT_GT(total_described, 20u);
}

TEST(SiftScaleSpace, EqualsVlFeatsToTheBit) {
  ExpectVlFeatsScaleSpace(203, 150, -1, 1);  // odd sizes: the halvings drop a column
  ExpectVlFeatsScaleSpace(203, 150, -1, 3);
  ExpectVlFeatsScaleSpace(256, 190, 0, 2);
  ExpectVlFeatsScaleSpace(400, 300, 1, 1);
}

TEST(SiftScaleSpace, LeavesFirstOctavesBelowMinusOneToVlFeat) {
  const std::vector<float> image = TestImage(100, 80, 3);
  Filter f = NewFilter(100, 80, -2);
  EXPECT_THROW(ProcessFirstOctave(f.get(), image.data(), 1), Error);
}

TEST(SiftScaleSpace, GaussianFilterIsVlFeatsWidthAndSumsToOne) {
  const std::vector<float> f = VlFeatGaussianFilter(1.249);
  ASSERT_EQ(f.size(), 2u * 5 + 1);  // ceil(4 sigma) = 5 on each side
  float sum = 0;
  for (float c : f) sum += c;
  EXPECT_NEAR(sum, 1.0f, 1e-6f);
  for (size_t i = 0; i < f.size(); ++i) EXPECT_EQ(f[i], f[f.size() - 1 - i]);
  EXPECT_GT(f[5], f[4]);
  EXPECT_EQ(VlFeatGaussianFilter(0.1).size(), 3u);  // at least one tap each side
}

// The whole colmap extractor on a real photo: the same keypoints and
// descriptors as with VLFeat's own scale space, on one and two threads.
TEST(SiftScaleSpace, ExtractorGivesVlFeatsFeaturesOnAnyThreadCount) {
  LINECLOUD_REQUIRE_DATA("strecha/Herz-Jesus-P8/images/0003.jpg");
  const GreyImage photo = ReadGreyImage(DataPath("strecha/Herz-Jesus-P8/images/0003.jpg"));
  SiftOptions reference;
  reference.extractor = SiftExtractor::kColmap;
  reference.vlfeat_scale_space = true;
  const SiftFeatures expected = ExtractSift(photo, reference);
  ASSERT_GT(expected.size(), 5000u);
  for (int threads : {1, 2}) {
    SiftOptions options;
    options.extractor = SiftExtractor::kColmap;
    options.threads = threads;
    const SiftFeatures got = ExtractSift(photo, options);
    ASSERT_EQ(got.size(), expected.size()) << threads << " threads";
    size_t differ = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      const SiftKeypoint& a = got.keypoints[i];
      const SiftKeypoint& b = expected.keypoints[i];
      differ += a.x != b.x || a.y != b.y || a.scale != b.scale || a.orientation != b.orientation;
    }
    EXPECT_EQ(differ, 0u) << threads << " threads";
    EXPECT_EQ(got.descriptors, expected.descriptors) << threads << " threads";
  }
}

// The scale-space buffers are pooled across extractions: a photo's features
// do not depend on the photo extracted before it.
TEST(SiftScaleSpace, PooledBuffersKeepNoTraceOfThePreviousPhoto) {
  LINECLOUD_REQUIRE_DATA("strecha/fountain-P11/images/0000.jpg");
  LINECLOUD_REQUIRE_DATA("strecha/entry-P10/images/0004.jpg");
  const GreyImage a = ReadGreyImage(DataPath("strecha/entry-P10/images/0004.jpg"));
  const GreyImage b = ReadGreyImage(DataPath("strecha/fountain-P11/images/0000.jpg"));
  ASSERT_EQ(a.width, b.width);  // the same buffer sizes: each is reused
  SiftOptions options;
  options.extractor = SiftExtractor::kColmap;
  const SiftFeatures first = ExtractSift(a, options);
  ExtractSift(b, options);
  const SiftFeatures again = ExtractSift(a, options);
  ASSERT_GT(first.size(), 5000u);
  ASSERT_EQ(again.size(), first.size());
  EXPECT_EQ(again.descriptors, first.descriptors);
  size_t moved = 0;
  for (size_t i = 0; i < first.size(); ++i) {
    moved += again.keypoints[i].x != first.keypoints[i].x ||
             again.keypoints[i].y != first.keypoints[i].y ||
             again.keypoints[i].orientation != first.keypoints[i].orientation;
  }
  EXPECT_EQ(moved, 0u);
}

TEST(SiftScaleSpace, RefusesImagesTooSmallForTheOctaves) {
  GreyImage tiny;
  tiny.width = 12;
  tiny.height = 9;
  tiny.pixels.assign(12 * 9, 128);
  SiftOptions options;
  options.extractor = SiftExtractor::kColmap;
  options.num_octaves = 5;  // the fifth octave would be 1 pixel high
  EXPECT_THROW(ExtractSift(tiny, options), Error);
  options.threads = 0;
  options.num_octaves = 4;
  EXPECT_THROW(ExtractSift(tiny, options), Error);
}

// SetSiftMemoryLimit for one test; the process's limit is none again after it.
class SiftMemoryLimitFor {
 public:
  explicit SiftMemoryLimitFor(size_t bytes) { SetSiftMemoryLimit(bytes); }
  ~SiftMemoryLimitFor() { SetSiftMemoryLimit(0); }
};

GreyImage TestGrey(int width, int height, uint32_t seed) {
  const std::vector<float> values = TestImage(width, height, seed);
  GreyImage image;
  image.width = width;
  image.height = height;
  image.pixels.resize(values.size());
  for (size_t i = 0; i < values.size(); ++i) {
    image.pixels[i] = static_cast<uint8_t>(std::clamp(values[i], 0.0f, 1.0f) * 255.0f);
  }
  return image;
}

// SiftScaleSpaceBytes is what an extraction maps at most: with the limit set
// to exactly it, extraction succeeds (every mapping must fit the reservation,
// or Allocate fails), 2 MB less is refused up front naming both sizes, and a
// photo above max_image_size is charged as its downscaled size.
TEST(SiftMemory, TheEstimateBoundsWhatAnExtractionMaps) {
  const GreyImage image = TestGrey(640, 480, 3);
  const size_t need = SiftScaleSpaceBytes(image.width, image.height);
  // ~320 bytes per pixel at first octave -1, plus rounding to 2 MB pages.
  EXPECT_GT(need, size_t{300} * 640 * 480);
  EXPECT_LT(need, size_t{400} * 640 * 480 + (size_t{40} << 20));
  SiftFeatures unlimited = ExtractSiftColmap(image);
  {
    SiftMemoryLimitFor limit(need);
    SiftOptions threaded;
    threaded.threads = 2;
    const SiftFeatures bounded = ExtractSiftColmap(image, threaded);
    EXPECT_EQ(bounded.descriptors, unlimited.descriptors);
    EXPECT_EQ(SiftMemoryInUse().reserved, 0u);
    EXPECT_LE(SiftMemoryInUse().pooled, need);
  }
  {
    SiftMemoryLimitFor limit(need - (size_t{2} << 20));
    try {
      ExtractSiftColmap(image);
      ADD_FAILURE() << "extraction over the limit was not refused";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(fmt::format("needs {} MB", need >> 20)),
                std::string::npos)
          << e.what();
      EXPECT_NE(std::string(e.what()).find("memory limit"), std::string::npos) << e.what();
    }
    EXPECT_EQ(SiftMemoryInUse().reserved, 0u);
  }
  EXPECT_EQ(SiftScaleSpaceBytes(7000, 7000), SiftScaleSpaceBytes(3200, 3200));
  EXPECT_LT(SiftScaleSpaceBytes(3200, 3200), size_t{3700} << 20);
}

// Under a limit that holds one extraction, four threads extracting at once
// take turns (each waits for room) and all get the unlimited features; a
// waiter whose deadline passes gets DeadlinePassed, not a wait for ever.
TEST(SiftMemory, ExtractionsWaitForRoomUntilTheirDeadline) {
  const GreyImage image = TestGrey(480, 360, 5);
  const SiftFeatures expected = ExtractSiftColmap(image);
  const size_t need = SiftScaleSpaceBytes(image.width, image.height);
  SiftMemoryLimitFor limit(need + need / 2);
  std::vector<SiftFeatures> got(4);
  std::vector<std::thread> threads;
  for (size_t i = 0; i < got.size(); ++i) {
    threads.emplace_back([&, i] { got[i] = ExtractSiftColmap(image); });
  }
  for (std::thread& t : threads) t.join();
  for (const SiftFeatures& f : got) EXPECT_EQ(f.descriptors, expected.descriptors);
  EXPECT_EQ(SiftMemoryInUse().reserved, 0u);
  EXPECT_LE(SiftMemoryInUse().pooled, need + need / 2);

  // A live filter holds the room; a second extraction waits 200 ms, then stops.
  SiftFilter holder(image.width, image.height, 4, 3, -1, false);
  SiftOptions late;
  late.deadline = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
  const auto start = std::chrono::steady_clock::now();
  EXPECT_THROW(ExtractSiftColmap(image, late), DeadlinePassed);
  const double waited =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  EXPECT_GE(waited, 0.19);
  EXPECT_LT(waited, 5.0);  // a hang guard, not a timing claim
}

// A deadline already passed stops the extraction at its first octave.
TEST(SiftMemory, APassedDeadlineStopsTheExtraction) {
  SiftOptions o;
  o.deadline = std::chrono::steady_clock::now();
  EXPECT_THROW(ExtractSiftColmap(TestGrey(320, 240, 7), o), DeadlinePassed);
  EXPECT_EQ(SiftMemoryInUse().reserved, 0u);
}

}  // namespace
}  // namespace linecloud
