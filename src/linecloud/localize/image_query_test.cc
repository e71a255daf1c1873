#include "linecloud/localize/image_query.h"

#include <cstdint>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/testing/test_util.h"

namespace linecloud {
namespace {

using testing::SharedDataPath;

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
  const Reconstruction model = ReadColmapModel(SharedDataPath("colmap-maupertuis/reconstruction"));
  const MapDescriptors full =
      MapDescriptorsFromModel(model, SharedDataPath("colmap-maupertuis/colmap.db"));
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
  const std::string path = SharedDataPath("colmap-maupertuis/images/02.jpg");
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

}  // namespace
}  // namespace linecloud
