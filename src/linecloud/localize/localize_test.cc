#include "linecloud/localize/localize.h"

#include <numbers>
#include <random>

#include <gtest/gtest.h>

#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/testing/test_util.h"

namespace linecloud {
namespace {

constexpr double kDeg = std::numbers::pi / 180;

class LocalizeTest : public ::testing::TestWithParam<std::string_view> {};

// Every implemented method on synthetic queries: 1 px noise, 50 % outliers.
TEST_P(LocalizeTest, LocalizesNoisyQueriesWithHalfOutliers) {
  const MethodInfo& method = FindMethod(GetParam());
  std::mt19937_64 rng(2024);
  LocalizationInstanceOptions instance_options;
  instance_options.num_correspondences = 200;
  instance_options.inlier_ratio = 0.5;
  instance_options.local_noise = 0.002;
  LocalizeOptions options;
  // The 6-point methods need ~300 RANSAC iterations at 50 % outliers (1.5 ms
  // per minimal solve): fewer queries keep the sanitizer job short.
  const int kQueries = testing::InstanceCount(method.sample_size >= 6 ? 8 : 20);
  int localized = 0;
  double initial_px = 0, refined_px = 0;
  for (int k = 0; k < kQueries; ++k) {
    const LocalizationInstance inst = RandomLocalizationInstance(method, instance_options, rng);
    options.ransac.seed = k;
    const LocalizationMap map = method.lines ? LocalizationMap(inst.line_map)
                                             : LocalizationMap(inst.point_map);
    const LocalizeResult r = Localize(method, inst.query, map, options);
    if (!r.success) continue;
    const LocalizationError e = CompareLocalization(r.query_from_world, inst.truth);
    localized += e.rotation_rad < 1 * kDeg && e.position < 0.01 * inst.scene_size;
    initial_px += r.reprojection_initial_px / kQueries;
    refined_px += r.reprojection_refined_px / kQueries;
    int true_inliers = 0;
    for (const int i : r.inliers) true_inliers += inst.is_inlier[i];
    EXPECT_GE(true_inliers, 0.9 * static_cast<double>(r.inliers.size())) << method.name;
  }
  std::cout << "[ " << method.name << " ] localized " << localized << " / " << kQueries
            << ", mean reprojection px initial " << initial_px << " refined " << refined_px
            << "\n";
  EXPECT_GE(localized, kQueries - 1) << method.name;
  EXPECT_LE(refined_px, initial_px * 1.001) << method.name;
}

INSTANTIATE_TEST_SUITE_P(Methods, LocalizeTest,
                         ::testing::ValuesIn(testing::ImplementedMethodNames()),
                         testing::MethodTestName);

// Real data: image 03.jpg of ../shared/data/colmap-maupertuis as a query (its
// 611 COLMAP observations with their point ids), against the point model
// (p3P) and against the line cloud lifted from it with a fresh key (p6L):
// both must give back COLMAP's own pose of that image — to ~0.01° for the
// points, and within 0.06° / 1 % for the lines, whose refined optimum moves
// with the random line directions (COLMAP's bundle adjustment minimised the
// point-to-point error with the points free).
TEST(Localize, RealImageAgainstItsModelAndLineCloud) {
  LINECLOUD_REQUIRE_DATA("colmap-maupertuis/reconstruction");
  const Reconstruction model =
      ReadColmapModel(testing::SharedDataPath("colmap-maupertuis/reconstruction"));
  const Image* image = nullptr;
  for (const auto& [id, im] : model.images) {
    if (im.name == "03.jpg") image = &im;
  }
  ASSERT_NE(image, nullptr);
  Query query;
  query.cameras.push_back(model.cameras.at(image->camera_id));
  for (const Point2D& p : image->points2D) {
    if (p.point3D_id != kInvalidPoint3DId) query.observations.push_back({0, p.xy, p.point3D_id, std::nullopt});
  }
  ASSERT_GT(query.observations.size(), 500u);
  std::vector<uint64_t> ids = model.SortedPoint3DIds();
  std::vector<Eigen::Vector3d> points;
  for (uint64_t id : ids) points.push_back(model.points3D.at(id).xyz);
  const LiftingKey key = DemoLiftingKey();
  const LineCloud cloud = LiftPoints(ids, points, key, {});
  LocalizeOptions options;
  for (const auto& [name, map] :
       {std::pair<const char*, LocalizationMap>{"p3P", PointMapFromModel(model)},
        std::pair<const char*, LocalizationMap>{"p6L", LineMapByPointId(cloud, key)}}) {
    const LocalizeResult r = Localize(FindMethod(name), query, map, options);
    ASSERT_TRUE(r.success) << name;
    const Rigid3d& truth = image->cam_from_world;
    const bool lines = std::string_view(name) == "p6L";
    EXPECT_LT(r.query_from_world.rotation.angularDistance(truth.rotation), lines ? 1e-3 : 2e-4)
        << name;
    EXPECT_LT((r.query_from_world.translation - truth.translation).norm(),
              (lines ? 1e-2 : 1e-3) * std::max(1.0, truth.translation.norm()))
        << name;
    EXPECT_GE(r.inliers.size(), 0.95 * query.observations.size()) << name;
    EXPECT_LT(r.reprojection_refined_px, 1.0) << name;
  }
}

TEST(Localize, BadInputGetsAClearError) {
  std::mt19937_64 rng(1);
  const MethodInfo& p3p = FindMethod("p3P");
  LocalizationInstanceOptions o;
  o.num_correspondences = 20;
  const LocalizationInstance inst = RandomLocalizationInstance(p3p, o, rng);
  const LocalizationMap points(inst.point_map), lines(inst.line_map);
  const LocalizeOptions options;
  const auto error = [&](const MethodInfo& m, const Query& q, const LocalizationMap& map) {
    return testing::ErrorOf([&] { Localize(m, q, map, options, "q.json"); });
  };
  EXPECT_NE(error(p3p, inst.query, lines).find("needs a point model"), std::string::npos);
  EXPECT_NE(error(FindMethod("p4L+u"), inst.query, points).find("needs a line cloud"),
            std::string::npos);
  Query q = inst.query;
  q.observations.resize(2);
  EXPECT_NE(error(p3p, q, points).find("needs at least 3 observations"), std::string::npos);
  q = inst.query;
  q.observations[4].id = 999999;
  EXPECT_NE(error(p3p, q, points).find("observations[4].id = 999999 is not in the map"),
            std::string::npos);
  q = inst.query;
  q.observations[2].camera = 3;
  EXPECT_NE(error(p3p, q, points).find("observations[2].camera = 3"), std::string::npos);
  q = inst.query;
  q.observations[1].xy.x() = std::nan("");
  EXPECT_NE(error(p3p, q, points).find("observations[1].xy is not finite"), std::string::npos);
  q = inst.query;
  q.gravity_query.reset();
  EXPECT_NE(error(FindMethod("p2P+u"), q, points).find("needs 'gravity_query'"),
            std::string::npos);
  EXPECT_NE(error(FindMethod("m-P3P+l"), inst.query, points).find("points_local"),
            std::string::npos);
}

}  // namespace
}  // namespace linecloud
