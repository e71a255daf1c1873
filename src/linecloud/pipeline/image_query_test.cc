#include "linecloud/pipeline/image_query.h"

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using testing::DataPath;

void ExpectSameQuery(const ImageQuery& a, const ImageQuery& b) {
  ASSERT_EQ(a.matches.size(), b.matches.size());
  for (size_t i = 0; i < a.matches.size(); ++i) {
    EXPECT_EQ(a.matches[i].query, b.matches[i].query) << i;
    EXPECT_EQ(a.matches[i].map, b.matches[i].map) << i;
    EXPECT_EQ(a.matches[i].ratio, b.matches[i].ratio) << i;
  }
  ASSERT_EQ(a.query.observations.size(), b.query.observations.size());
  for (size_t i = 0; i < a.query.observations.size(); ++i) {
    EXPECT_EQ(a.query.observations[i].xy, b.query.observations[i].xy) << i;
    EXPECT_EQ(a.query.observations[i].id, b.query.observations[i].id) << i;
  }
  ASSERT_EQ(a.query.cameras.size(), 1u);
  ASSERT_EQ(b.query.cameras.size(), 1u);
}

// A photo extracted once and matched to two maps (as `eval privacy` does for
// every lifting) gives what extracting it again for each map gives, and an
// earlier match leaves nothing behind.
TEST(ImageQuery, ExtractedOnceMatchesEachMapAsAFreshExtraction) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Reconstruction model = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  const MapDescriptors full =
      MapDescriptorsFromModel(model, DataPath("colmap-maupertuis/colmap.db"));
  MapDescriptors half;  // every other descriptor: another map
  for (size_t i = 0; i < full.ids.size(); i += 2) {
    half.ids.push_back(full.ids[i]);
    half.descriptors.insert(half.descriptors.end(), full.descriptors.begin() + 128 * i,
                            full.descriptors.begin() + 128 * (i + 1));
  }
  const Image* image = nullptr;
  for (const auto& [id, im] : model.images) {
    if (im.name == "02.jpg") image = &im;
  }
  ASSERT_NE(image, nullptr);
  const Camera& camera = model.cameras.at(image->camera_id);
  const std::string path = DataPath("colmap-maupertuis/images/02.jpg");
  ImageQueryOptions o;
  o.sift.max_image_size = 960;  // half size: a quarter of the time

  ImageQuery once = ExtractImageQuery(path, camera, o);
  ASSERT_GT(once.features.size(), 500u);
  EXPECT_TRUE(once.matches.empty());
  MatchImageQuery(once, camera, full, o);
  const ImageQuery fresh_full = QueryFromImage(path, camera, full, o);
  ASSERT_GT(fresh_full.matches.size(), 50u);
  ExpectSameQuery(once, fresh_full);

  MatchImageQuery(once, camera, half, o);
  const ImageQuery fresh_half = QueryFromImage(path, camera, half, o);
  // Another map, other matches (half the map's points, some now distinctive).
  std::vector<uint64_t> ids_full, ids_half;
  for (const QueryObservation& ob : fresh_full.query.observations) ids_full.push_back(ob.id);
  for (const QueryObservation& ob : fresh_half.query.observations) ids_half.push_back(ob.id);
  EXPECT_NE(ids_full, ids_half);
  ExpectSameQuery(once, fresh_half);
}

// [guard]: the library keeps no per-call global state (FreeImage's message
// callback, SIFT, the matching index's random generator, RANSAC): photos
// localized on 8 threads at once give exactly what one thread gives.
TEST(ImageQuery, EightThreadsGiveWhatOneThreadGives) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/colmap.db");
  const Reconstruction model = ReadColmapModel(DataPath("colmap-maupertuis/reconstruction"));
  const MapDescriptors map =
      MapDescriptorsFromModel(model, DataPath("colmap-maupertuis/colmap.db"));
  const DescriptorIndex index(map.descriptors, {});  // shared by every thread
  const LocalizationMap points(PointMapFromModel(model));
  const MethodInfo& method = FindMethod("p3P");
  ImageQueryOptions o;
  o.sift.max_image_size = 640;  // the test is about threads, not accuracy
  struct Photo {
    std::string path;
    const Camera* camera;
  };
  std::vector<Photo> photos;
  for (const auto& [id, im] : model.images) {
    photos.push_back(
        {DataPath("colmap-maupertuis/images/" + im.name), &model.cameras.at(im.camera_id)});
  }
  ASSERT_GE(photos.size(), 4u);
  struct Outcome {
    ImageQuery query;
    LocalizeResult result;
  };
  const auto localize = [&](const Photo& p, bool approximate) {
    Outcome out;
    out.query = QueryFromImage(p.path, *p.camera, map, o, approximate ? &index : nullptr);
    LocalizeOptions lo;
    lo.ransac.seed = 7;
    out.result = Localize(method, out.query.query, points, lo);
    return out;
  };
  const int jobs = testing::InstanceCount(16) >= 8 ? 16 : 8;
  std::vector<Outcome> one(jobs), eight(jobs);
  for (int j = 0; j < jobs; ++j) one[j] = localize(photos[j % photos.size()], j % 2);
  std::vector<std::thread> threads;
  std::atomic<int> next{0};
  for (int t = 0; t < 8; ++t) {
    threads.emplace_back([&] {
      for (int j; (j = next++) < jobs;) eight[j] = localize(photos[j % photos.size()], j % 2);
    });
  }
  for (std::thread& t : threads) t.join();
  for (int j = 0; j < jobs; ++j) {
    SCOPED_TRACE(photos[j % photos.size()].path);
    ASSERT_EQ(one[j].query.features.size(), eight[j].query.features.size());
    ExpectSameQuery(one[j].query, eight[j].query);
    EXPECT_EQ(one[j].result.success, eight[j].result.success);
    EXPECT_EQ(one[j].result.inliers, eight[j].result.inliers);
    EXPECT_EQ(one[j].result.query_from_world.rotation.coeffs(),
              eight[j].result.query_from_world.rotation.coeffs());
    EXPECT_EQ(one[j].result.query_from_world.translation,
              eight[j].result.query_from_world.translation);
  }
}

}  // namespace
}  // namespace linecloud

namespace linecloud {
namespace {

// A photo's query with `n` keypoints, keypoint i matched to map id 100 + i
// for every i in `matched`.
ImageQuery PhotoWithMatches(int n, const std::vector<int>& matched) {
  ImageQuery q;
  q.features.keypoints.resize(n);
  q.query.cameras.push_back(Camera{});
  for (const int i : matched) {
    q.matches.push_back({i, i, 0.5f});
    q.query.observations.push_back(
        {0, Eigen::Vector2d(i, i), static_cast<uint64_t>(100 + i), std::nullopt, 0.5});
  }
  return q;
}

// [rigs] With a device's local points only the matches of keypoints that
// carry one are kept, in order, each with its point; without them every match.
TEST(ImageQuery, CombinedRigKeepsTheMatchesWithALocalPoint) {
  const std::vector<ImageQuery> photos = {PhotoWithMatches(10, {1, 4, 7}),
                                          PhotoWithMatches(5, {0, 2})};
  const std::vector<Rigid3d> rig(2);
  EXPECT_EQ(CombineImageQueries(photos, rig).observations.size(), 5u);
  const std::vector<LocalPoint> points = {{.frame = 1, .keypoint = 2, .xyz = {1, 2, 3}},
                                          {.frame = 0, .keypoint = 7, .xyz = {4, 5, 6}},
                                          {.frame = 0, .keypoint = 9, .xyz = {7, 8, 9}}};
  const Query q = CombineImageQueries(photos, rig, points);
  ASSERT_EQ(q.observations.size(), 2u);
  ASSERT_EQ(q.points_local.size(), 2u);
  EXPECT_EQ(q.observations[0].id, 107u);
  EXPECT_EQ(q.observations[0].camera, 0);
  EXPECT_EQ(q.points_local[0], Eigen::Vector3d(4, 5, 6));
  EXPECT_EQ(q.observations[1].id, 102u);
  EXPECT_EQ(q.observations[1].camera, 1);
  EXPECT_EQ(q.points_local[1], Eigen::Vector3d(1, 2, 3));
  const auto error = [&](std::vector<LocalPoint> bad) {
    try {
      CombineImageQueries(photos, rig, bad);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error({{.frame = 2, .keypoint = 0}}),
            "points_local[0]: frame 2 is not one of the 2 photos");
  EXPECT_EQ(error({{.frame = 1, .keypoint = 5}}),
            "points_local[0]: frame 1 has 5 keypoints, no keypoint 5");
  EXPECT_EQ(error({{.frame = 0, .keypoint = 3}, {.frame = 0, .keypoint = 3}}),
            "points_local[1]: frame 0 keypoint 3 has a local point already");
}

}  // namespace
}  // namespace linecloud
