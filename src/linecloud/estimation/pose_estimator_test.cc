#include "linecloud/estimation/pose_estimator.h"

#include <random>

#include <gtest/gtest.h>

#include "linecloud/localize/localize.h"
#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/testing/test_util.h"

namespace linecloud {
namespace {

// [harden] 7: the public entry points that take PoseData check it instead
// of indexing past the end of a shorter array.
TEST(PoseEstimator, PreconditionsAtTheEntryPoints) {
  const MethodInfo& p6l = FindMethod("p6L");
  std::mt19937_64 rng(8);
  LocalizationInstanceOptions options;
  options.num_correspondences = 40;
  const LocalizationInstance inst = RandomLocalizationInstance(p6l, options, rng);
  const PreparedQuery prepared = PrepareQuery(p6l, inst.query, LocalizationMap(inst.line_map));
  PoseData short_focal = prepared.data;
  short_focal.focal.pop_back();
  EXPECT_NE(testing::ErrorOf([&] {
              PoseEstimator(p6l, short_focal, RefineOptions{});
            }).find("PoseEstimator: pose data has 40 cameras but 39 focal lengths"),
            std::string::npos);
  PoseData bad_camera = prepared.data;
  bad_camera.camera[3] = 2;
  EXPECT_NE(testing::ErrorOf([&] {
              PoseEstimator(p6l, bad_camera, RefineOptions{});
            }).find("correspondence 3 has camera 2"),
            std::string::npos);
  EXPECT_NE(testing::ErrorOf([&] {
              PoseEstimator(FindMethod("p3P"), prepared.data, {});
            }).find("method p3P needs points"),
            std::string::npos);
  Sim3d pose = inst.truth;
  const std::vector<int> out_of_range = {0, 1, 40};
  EXPECT_NE(testing::ErrorOf([&] {
              RefinePose(prepared.data, out_of_range, {}, &pose);
            }).find("RefinePose: correspondence index 40 out of range"),
            std::string::npos);
  EXPECT_THROW(RefinePose(prepared.data, std::vector<int>{0}, {}, nullptr), Error);
  EXPECT_THROW(EstimatePoseUncertainty(prepared.data, out_of_range, pose, false), Error);
}

class PoseEstimatorTest : public ::testing::TestWithParam<std::string_view> {};

// Scoring: the true pose counts the true inliers; with the best score as a
// bound, the true pose is never dropped by the SPRT while a wrong pose is
// (score ≥ bound or +∞); the minimal solver on an all-inlier sample of
// noise-free data returns the true pose.
TEST_P(PoseEstimatorTest, ScoresTheTruePoseAndRejectsWrongOnes) {
  const MethodInfo& method = FindMethod(GetParam());
  std::mt19937_64 rng(3);
  LocalizationInstanceOptions options;
  options.num_correspondences = 300;
  options.inlier_ratio = 0.6;
  options.noise_px = 0.0;  // noise-free: the minimal solvers must return the truth
  options.local_noise = 0;
  for (int trial = 0; trial < 10; ++trial) {
    const LocalizationInstance inst = RandomLocalizationInstance(method, options, rng);
    const LocalizationMap map =
        method.lines ? LocalizationMap(inst.line_map) : LocalizationMap(inst.point_map);
    const PreparedQuery prepared = PrepareQuery(method, inst.query, map);
    PoseEstimator estimator(method, prepared.data, RefineOptions{});
    // The truth in the solvers' (gravity-aligned) frames.
    const Sim3d aligned_truth =
        Sim3d(1.0, prepared.aligned_from_query, Eigen::Vector3d::Zero()) * inst.truth *
        Sim3d(1.0, prepared.aligned_from_map.inverse(), Eigen::Vector3d::Zero());
    constexpr double kThreshold = 4.0;
    int inliers = 0;
    const double score = estimator.score_model(aligned_truth, kThreshold,
                                               std::numeric_limits<double>::infinity(), &inliers);
    int true_inliers = 0;
    for (char c : inst.is_inlier) true_inliers += c;
    EXPECT_GE(inliers, true_inliers * 99 / 100) << method.name;
    EXPECT_LE(inliers, true_inliers + 6) << method.name;  // chance agreements
    int bounded_inliers = 0;
    EXPECT_DOUBLE_EQ(
        estimator.score_model(aligned_truth, kThreshold, 1.01 * score, &bounded_inliers), score);
    // 5° and 5 % of the scene off: a wrong model.
    Eigen::Matrix<double, 7, 1> offset;
    offset << 0.05, -0.06, 0.04, 0.5, -0.3, 0.2, 0.0;
    const Sim3d wrong = PerturbPose(aligned_truth, offset);
    EXPECT_GE(estimator.score_model(wrong, kThreshold, 1.01 * score, &bounded_inliers),
              1.01 * score);
    // An all-inlier sample gives back the truth (up to the noise).
    std::vector<int> sample;
    for (int i = 0; sample.size() < static_cast<size_t>(method.sample_size); ++i) {
      if (inst.is_inlier[i]) sample.push_back(i);
    }
    std::vector<Sim3d> models;
    estimator.generate_models(sample, &models);
    double best = 1e9;
    for (const Sim3d& m : models) {
      best = std::min(best, m.rotation.angularDistance(aligned_truth.rotation));
    }
    EXPECT_LT(best, 1e-6) << method.name << " trial " << trial;
  }
}

INSTANTIATE_TEST_SUITE_P(Methods, PoseEstimatorTest,
                         ::testing::ValuesIn(testing::ImplementedMethodNames()),
                         testing::MethodTestName);

}  // namespace
}  // namespace linecloud
