#include "linecloud/estimation/refine_pose.h"

#include <random>

#include <gtest/gtest.h>

#include "linecloud/synthetic/random.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// Noise-free correspondences of a 3-camera rig (or one camera at the origin)
// seeing points, optionally replaced by random lines through them.
PoseData RandomPoseData(bool lines, bool rig, const Sim3d& query_from_world,
                        std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PoseData d;
  const int cameras = rig ? 3 : 1;
  for (int c = 0; c < cameras; ++c) {
    d.cam_from_rig.push_back(rig ? Rigid3d(RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng)))
                                 : Rigid3d());
  }
  const Sim3d world_from_query = query_from_world.Inverse();
  for (int i = 0; i < 60; ++i) {
    const int c = i % cameras;
    const Eigen::Vector3d x_cam = Eigen::Vector3d(u(rng), u(rng), 1.0) * (3.0 + 2 * u(rng));
    const Eigen::Vector3d x = world_from_query * (d.cam_from_rig[c].Inverse() * x_cam);
    d.camera.push_back(c);
    d.normalized.push_back(x_cam.head<2>() / x_cam.z());
    d.focal.push_back(500.0);
    d.bearings.push_back(x_cam.normalized());
    if (lines) {
      d.lines.push_back(PluckerLine::FromPointAndDirection(x, RandomUnit(rng)));
    } else {
      d.points.push_back(x);
    }
  }
  return d;
}

Sim3d RandomPose(std::mt19937_64& rng, bool similarity) {
  std::normal_distribution<double> g(0.0, 1.0);
  return Sim3d(similarity ? std::exp(g(rng)) : 1.0, RandomRotation(rng),
               Eigen::Vector3d(g(rng), g(rng), g(rng)));
}

class RefinePoseTest : public ::testing::TestWithParam<std::tuple<bool, bool, bool>> {};

TEST_P(RefinePoseTest, JacobiansMatchCentralDifferences) {
  const auto [lines, rig, similarity] = GetParam();
  std::mt19937_64 rng(7);
  const Sim3d truth = RandomPose(rng, similarity);
  const PoseData d = RandomPoseData(lines, rig, truth, rng);
  // Evaluate away from the optimum so that residuals are not zero.
  Eigen::Matrix<double, 7, 1> offset;
  offset << 0.02, -0.01, 0.03, 0.1, -0.05, 0.02, similarity ? 0.05 : 0.0;
  const Sim3d pose = PerturbPose(truth, offset);
  double worst = 0;
  for (size_t i = 0; i < d.size(); ++i) {
    Eigen::Vector2d r;
    Eigen::Matrix<double, 2, 7> j;
    const int n = ReprojectionResidual(d, pose, i, &r, &j);
    ASSERT_GT(n, 0);
    for (int k = 0; k < 7; ++k) {
      constexpr double h = 1e-6;
      Eigen::Matrix<double, 7, 1> delta = Eigen::Matrix<double, 7, 1>::Zero();
      delta[k] = h;
      Eigen::Vector2d rp, rm;
      ReprojectionResidual(d, PerturbPose(pose, delta), i, &rp, nullptr);
      ReprojectionResidual(d, PerturbPose(pose, -delta), i, &rm, nullptr);
      const Eigen::Vector2d numeric = (rp - rm) / (2 * h);
      for (int row = 0; row < n; ++row) {
        worst = std::max(worst, std::abs(numeric[row] - j(row, k)) /
                                    std::max(1.0, std::abs(numeric[row])));
      }
    }
  }
  EXPECT_LT(worst, 1e-5);
}

TEST_P(RefinePoseTest, RecoversThePoseFromAPerturbedStart) {
  const auto [lines, rig, similarity] = GetParam();
  std::mt19937_64 rng(11);
  for (int trial = 0; trial < 20; ++trial) {
    const Sim3d truth = RandomPose(rng, similarity);
    const PoseData d = RandomPoseData(lines, rig, truth, rng);
    std::normal_distribution<double> g(0.0, 0.02);
    Eigen::Matrix<double, 7, 1> offset;
    offset << g(rng), g(rng), g(rng), g(rng), g(rng), g(rng), similarity ? g(rng) : 0.0;
    Sim3d pose = PerturbPose(truth, offset);
    std::vector<int> all(d.size());
    for (size_t i = 0; i < d.size(); ++i) all[i] = static_cast<int>(i);
    RefineOptions options;
    options.similarity = similarity;
    options.max_iterations = 50;
    const RefineSummary summary = RefinePose(d, all, options, &pose);
    EXPECT_LT(summary.final_cost, summary.initial_cost);
    EXPECT_LT(pose.rotation.angularDistance(truth.rotation), 1e-8) << "trial " << trial;
    // A single camera at the rig origin cannot see the scale: compare the
    // direction of the translation and the rotation only.
    if (similarity && !rig) {
      EXPECT_LT((pose.translation / pose.scale - truth.translation / truth.scale).norm(), 1e-7);
    } else {
      EXPECT_LT((pose.translation - truth.translation).norm(), 1e-7) << "trial " << trial;
      EXPECT_NEAR(pose.scale, truth.scale, 1e-8 * truth.scale);
    }
  }
}

INSTANTIATE_TEST_SUITE_P(
    AllCases, RefinePoseTest,
    ::testing::Combine(::testing::Bool(), ::testing::Bool(), ::testing::Bool()),
    [](const auto& info) {
      return std::string(std::get<0>(info.param) ? "Lines" : "Points") +
             (std::get<1>(info.param) ? "Rig" : "Single") +
             (std::get<2>(info.param) ? "Sim3" : "SE3");
    });

TEST(RefinePose, RejectsBadOptions) {
  RefineOptions options;
  options.loss_scale = 0;
  EXPECT_THROW(options.Check(), Error);
}

}  // namespace
}  // namespace linecloud
