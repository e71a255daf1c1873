#include "linecloud/localize/localize.h"

#include <numbers>
#include <random>

#include <gtest/gtest.h>

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
