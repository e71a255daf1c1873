#include "linecloud/pipeline/localizer.h"

#include <atomic>
#include <cmath>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

using testing::DataPath;
using testing::ErrorOf;

void ExpectSamePose(const LocalizerResult& a, const LocalizerResult& b) {
  EXPECT_EQ(a.status, b.status);
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.pose.inliers, b.pose.inliers);
  EXPECT_EQ(a.pose.query_from_world.rotation.coeffs(), b.pose.query_from_world.rotation.coeffs());
  EXPECT_EQ(a.pose.query_from_world.translation, b.pose.query_from_world.translation);
}

// A query of correspondences through the Localizer is exactly Localize().
TEST(Localizer, AQueryGivesWhatLocalizeGives) {
  for (const char* name : {"p6L", "p3P", "m-p6L"}) {
    const MethodInfo& method = FindMethod(name);
    std::mt19937_64 rng(3);
    const LocalizationInstance inst = RandomLocalizationInstance(method, {}, rng);
    LocalizeOptions options;
    options.ransac.seed = 5;
    LocalizerOptions lo;
    lo.localize = options;
    LineCloud cloud;
    for (const auto& [id, line] : inst.line_map.lines) {
      cloud.ids.push_back(id);
      cloud.lines.push_back(line);
    }
    const LocalizeResult direct = Localize(
        method, inst.query,
        method.lines ? LocalizationMap(inst.line_map) : LocalizationMap(inst.point_map), options);
    ASSERT_TRUE(direct.success) << name << ": " << direct.failure;
    if (!method.lines) continue;  // a point map needs a model: the photo tests below
    const Localizer localizer(cloud, lo);
    LocalizeRequest request;
    request.method = name;
    const LocalizerResult r = localizer.LocalizeQuery(inst.query, request);
    EXPECT_TRUE(r.success()) << r.reason;
    EXPECT_EQ(r.method, name);
    EXPECT_EQ(r.pose.inliers, direct.inliers);
    EXPECT_EQ(r.pose.query_from_world.translation, direct.query_from_world.translation);
    EXPECT_EQ(r.pose.query_from_world.rotation.coeffs(), direct.query_from_world.rotation.coeffs());
    EXPECT_GE(r.times.total_ms, r.times.ransac_ms);
  }
}

// A request's options replace the Localizer's for that request only, and a
// caller that stops waiting (should_stop) ends RANSAC with no pose.
TEST(Localizer, RequestOptionsAndStopping) {
  const MethodInfo& method = FindMethod("p6L");
  std::mt19937_64 rng(4);
  const LocalizationInstance inst = RandomLocalizationInstance(method, {}, rng);
  LineCloud cloud;
  for (const auto& [id, line] : inst.line_map.lines) {
    cloud.ids.push_back(id);
    cloud.lines.push_back(line);
  }
  const Localizer localizer(cloud);
  LocalizeRequest request;
  request.options = localizer.options().localize;
  request.options->ransac.max_iterations = 3;
  request.options->ransac.min_iterations = 3;
  request.options->ransac.progressive_sampling = false;
  const LocalizerResult few = localizer.LocalizeQuery(inst.query, request);
  EXPECT_LE(few.pose.stats.iterations, 3);
  const LocalizerResult plain = localizer.LocalizeQuery(inst.query);
  EXPECT_TRUE(plain.success()) << plain.reason;
  EXPECT_GT(plain.pose.stats.iterations, 3) << "the request's options did not stay with it";
  request.options->ransac.max_error = -1;
  EXPECT_NE(ErrorOf([&] { localizer.LocalizeQuery(inst.query, request); }).find("threshold"),
            std::string::npos);
  // Stopped after a few polls: no pose, the reason says so.
  LocalizeRequest stop;
  stop.options = localizer.options().localize;
  stop.options->ransac.min_iterations = stop.options->ransac.max_iterations = 10000000;
  int polls = 0;
  stop.should_stop = [&] { return ++polls > 3; };
  const LocalizerResult stopped = localizer.LocalizeQuery(inst.query, stop);
  EXPECT_FALSE(stopped.success());
  EXPECT_NE(stopped.reason.find("stopped by the caller"), std::string::npos) << stopped.reason;
  EXPECT_EQ(polls, 4);
  EXPECT_LT(stopped.pose.stats.iterations, 10000000);
  stop.should_stop = [] { return true; };
  EXPECT_EQ(localizer.LocalizeQuery(inst.query, stop).reason,
            "stopped by the caller before RANSAC");
}

struct Maupertuis {
  Reconstruction model;
  std::string database;
  std::vector<std::pair<std::string, const Camera*>> photos;  // path, camera
};

Maupertuis LoadMaupertuis() {
  Maupertuis m;
  m.model = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  m.database = DataPath("colmap-maupertuis/colmap.db");
  for (const auto& [id, im] : m.model.images) {
    m.photos.emplace_back(DataPath("colmap-maupertuis/images/" + im.name),
                          &m.model.cameras.at(im.camera_id));
  }
  return m;
}

LocalizerOptions SmallPhotos() {
  LocalizerOptions o;
  o.image.sift.max_image_size = 640;  // these tests are about the paths, not accuracy
  o.localize.ransac.seed = 11;
  return o;
}

// The same photo as encoded bytes, as a decoded image and as its features:
// the same matches and pose; its query localizes to the same pose again.
TEST(Localizer, BytesImagesAndFeaturesGiveOnePose) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Maupertuis m = LoadMaupertuis();
  const LocalizerOptions options = SmallPhotos();
  const Localizer localizer(m.model, m.database, options);
  EXPECT_FALSE(localizer.lines());
  EXPECT_EQ(localizer.size(), m.model.points3D.size());
  const auto& [path, camera] = m.photos.at(0);
  const std::string bytes = ReadFileToString(path);
  const std::span<const uint8_t> encoded(reinterpret_cast<const uint8_t*>(bytes.data()),
                                         bytes.size());
  LocalizeRequest keep;
  keep.keep_images = true;
  const LocalizerResult from_bytes = localizer.LocalizeEncodedImage(encoded, *camera, keep, path);
  ASSERT_GT(from_bytes.num_matches(), 50u);
  EXPECT_EQ(from_bytes.method, "p3P");
  ASSERT_EQ(from_bytes.photos.size(), 1u);
  const GreyImage& image = from_bytes.photos[0].image;
  ASSERT_EQ(static_cast<uint64_t>(image.width), camera->width);
  const LocalizerResult from_image = localizer.LocalizeImage(image, *camera);
  const LocalizerResult from_features =
      localizer.LocalizeFeatures(from_bytes.photos[0].features, *camera);
  const LocalizerResult from_query = localizer.LocalizeQuery(from_bytes.query);
  for (const LocalizerResult* r : {&from_image, &from_features, &from_query}) {
    ExpectSamePose(from_bytes, *r);
  }
  EXPECT_EQ(from_image.num_matches(), from_bytes.num_matches());
  EXPECT_EQ(from_features.num_matches(), from_bytes.num_matches());
  EXPECT_TRUE(from_image.photos[0].image.pixels.empty());  // not kept unless asked
  EXPECT_GT(from_bytes.times.decode_ms, 0);
  EXPECT_EQ(from_features.times.extract_ms, 0);
}

// A caller that stops waiting during SIFT (Python's Ctrl-C) ends the request
// there: polled between the scale space's octaves and levels, no matching, no
// RANSAC (Ctrl-C during a photo's extraction took 5.9 s to be heard).
TEST(Localizer, StoppingDuringSiftEndsThere) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Maupertuis m = LoadMaupertuis();
  const Localizer localizer(m.model, m.database, SmallPhotos());
  const auto& [path, camera] = m.photos.at(0);
  const std::string bytes = ReadFileToString(path);
  const std::span<const uint8_t> encoded(reinterpret_cast<const uint8_t*>(bytes.data()),
                                         bytes.size());
  LocalizeRequest stop;
  int polls = 0;
  stop.should_stop = [&] { return ++polls > 5; };
  const LocalizerResult r = localizer.LocalizeEncodedImage(encoded, *camera, stop, path);
  EXPECT_FALSE(r.success());
  EXPECT_EQ(r.reason, "stopped by the caller during SIFT");
  EXPECT_EQ(polls, 6);  // stopped at the first poll that asked
  EXPECT_EQ(r.times.match_ms, 0);
  EXPECT_EQ(r.pose.stats.iterations, 0);
}

// One Localizer, 8 threads at once: bit-identical to one thread.
TEST(Localizer, EightThreadsOnOneLocalizerGiveWhatOneGives) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Maupertuis m = LoadMaupertuis();
  LocalizerOptions options = SmallPhotos();
  options.image.approximate_from = 1;  // the shared approximate index too
  const Localizer localizer(m.model, m.database, options);
  std::vector<std::string> bytes;
  for (const auto& [path, camera] : m.photos) bytes.push_back(ReadFileToString(path));
  const auto run = [&](size_t k) {
    const std::string& b = bytes[k % bytes.size()];
    return localizer.LocalizeEncodedImage(
        std::span(reinterpret_cast<const uint8_t*>(b.data()), b.size()),
        *m.photos[k % m.photos.size()].second);
  };
  const size_t jobs = 8;
  std::vector<LocalizerResult> one(jobs), eight(jobs);
  for (size_t k = 0; k < jobs; ++k) one[k] = run(k);
  std::atomic<size_t> next{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&] {
      for (size_t k; (k = next++) < jobs;) eight[k] = run(k);
    });
  }
  for (std::thread& t : threads) t.join();
  for (size_t k = 0; k < jobs; ++k) {
    EXPECT_EQ(one[k].num_matches(), eight[k].num_matches());
    ExpectSamePose(one[k], eight[k]);
  }
}

// The same photo re-encoded (a JPEG comment added: other bytes, the same
// pixels) as a second frame of a rig: the same map points at the same pixels,
// refused after matching; two different photos of the rig are not.
TEST(Localizer, ARigRefusesTheSameViewTwice) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Maupertuis m = LoadMaupertuis();
  const Localizer localizer(m.model, m.database, SmallPhotos());
  const std::string a = ReadFileToString(m.photos[0].first);
  ASSERT_GT(a.size(), 2u);
  const std::string comment("\xFF\xFE\x00\x07hello", 9);  // COM segment, 5 bytes of text
  const std::string a_again = a.substr(0, 2) + comment + a.substr(2);
  const std::string b = ReadFileToString(m.photos[1].first);
  auto frame = [&](const std::string& bytes, const Camera* camera, const char* name, double x) {
    QueryPhoto p;
    p.encoded = std::span(reinterpret_cast<const uint8_t*>(bytes.data()), bytes.size());
    p.camera = *camera;
    p.name = name;
    p.cam_from_rig.translation.x() = x;
    return p;
  };
  const std::vector<QueryPhoto> twice = {frame(a, m.photos[0].second, "frames[0]", 0),
                                         frame(a_again, m.photos[0].second, "frames[1]", 0.1)};
  const std::string error = ErrorOf([&] { localizer.LocalizePhotos(twice); });
  EXPECT_EQ(error.rfind("frames[1] shows what frames[0] shows (", 0), 0u) << error;
  EXPECT_NE(error.find("a rig's photos must be different views"), std::string::npos) << error;
  const std::vector<QueryPhoto> two = {frame(a, m.photos[0].second, "frames[0]", 0),
                                       frame(b, m.photos[1].second, "frames[1]", 0.1)};
  EXPECT_EQ(ErrorOf([&] { localizer.LocalizePhotos(two); }), "");
}

TEST(Localizer, BadRequestsGetErrorsNamingTheirPart) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Maupertuis m = LoadMaupertuis();
  const Localizer localizer(m.model, m.database, SmallPhotos());
  const Camera& camera = *m.photos[0].second;
  SiftFeatures features;
  features.keypoints.resize(2);
  features.descriptors.resize(128);
  EXPECT_NE(ErrorOf([&] {
              localizer.LocalizeFeatures(features, camera);
            }).find("features: 2 keypoints but 128 descriptor bytes"),
            std::string::npos);
  features.descriptors.resize(256);
  features.keypoints[1].x = std::nanf("");
  EXPECT_NE(ErrorOf([&] {
              localizer.LocalizeFeatures(features, camera);
            }).find("features: keypoints[1] = (nan, 0) is not a pixel"),
            std::string::npos);
  GreyImage small{
      .width = 10, .height = 10, .pixels = std::vector<uint8_t>(100), .orientation = {}};
  EXPECT_NE(ErrorOf([&] {
              localizer.LocalizeImage(small, camera);
            }).find("image: the image is 10x10 pixels but the camera is 1919x1079"),
            std::string::npos);
  QueryPhoto both;
  both.image = &small;
  both.features = &features;
  both.camera = camera;
  EXPECT_NE(ErrorOf([&] {
              localizer.LocalizePhotos(std::span(&both, 1));
            }).find("photo: give exactly one of"),
            std::string::npos);
  QueryPhoto one;
  one.image = &small;
  one.camera = camera;
  const std::vector<QueryPhoto> two(2, one);
  LocalizeRequest p3p;
  p3p.method = "p3P";
  EXPECT_NE(ErrorOf([&] { localizer.LocalizePhotos(two, p3p); }).find("use an m- method"),
            std::string::npos);
  // A rig's photos sent twice would count their matches twice: refused, whatever the source.
  std::vector<QueryPhoto> twice(2, one);
  twice[0].name = "frames[0]";
  twice[1].name = "frames[1]";
  twice[1].cam_from_rig.translation.x() = 0.1;
  EXPECT_EQ(ErrorOf([&] { localizer.LocalizePhotos(twice); }),
            "frames[1] is frames[0] again (the same pixels): a rig's photos must be different "
            "photos, a repeated one would count its matches twice");
  twice[0].image = twice[1].image = nullptr;
  twice[0].features = twice[1].features = &features;
  EXPECT_NE(ErrorOf([&] { localizer.LocalizePhotos(twice); }).find("(the same descriptors)"),
            std::string::npos);
  const std::vector<uint8_t> jpeg = {0xFF, 0xD8, 0xFF, 0xE0, 1, 2, 3};
  twice[0].features = twice[1].features = nullptr;
  twice[0].encoded = twice[1].encoded = jpeg;
  EXPECT_NE(ErrorOf([&] { localizer.LocalizePhotos(twice); }).find("(the same bytes)"),
            std::string::npos);
  // Different photos pass this check (and fail later, on their content).
  GreyImage other = small;
  other.pixels[0] = 1;
  twice[0].encoded = twice[1].encoded = {};
  twice[0].image = &small;
  twice[1].image = &other;
  EXPECT_EQ(ErrorOf([&] { localizer.LocalizePhotos(twice); }).find("again"), std::string::npos);
  // Few matches: no pose, a reason, no exception.
  features.keypoints[1].x = 3;
  const LocalizerResult r = localizer.LocalizeFeatures(features, camera);
  EXPECT_FALSE(r.success());
  EXPECT_NE(r.reason.find("fewer than the 3 the method's sample needs"), std::string::npos)
      << r.reason;
  // A point model without its database takes queries but not photos.
  const Localizer no_db(m.model, "", SmallPhotos(), "maupertuis");
  EXPECT_NE(ErrorOf([&] {
              no_db.LocalizeFeatures(features, camera);
            }).find("maupertuis: photos need the model's COLMAP database"),
            std::string::npos);
}

}  // namespace
}  // namespace linecloud
