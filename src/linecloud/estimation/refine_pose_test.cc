#include "linecloud/estimation/refine_pose.h"

#include <cmath>
#include <random>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/synthetic/random.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// Noise-free correspondences of a 3-camera rig (or one camera at the origin)
// seeing points, optionally replaced by random lines through them.
PoseData RandomPoseData(bool lines, bool rig, const Sim3d& query_from_world, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  PoseData d;
  const int cameras = rig ? 3 : 1;
  for (int c = 0; c < cameras; ++c) {
    d.cam_from_rig.push_back(
        rig ? Rigid3d(RandomRotation(rng), Eigen::Vector3d(u(rng), u(rng), u(rng))) : Rigid3d());
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
        worst = std::max(
            worst, std::abs(numeric[row] - j(row, k)) / std::max(1.0, std::abs(numeric[row])));
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

INSTANTIATE_TEST_SUITE_P(AllCases, RefinePoseTest,
                         ::testing::Combine(::testing::Bool(), ::testing::Bool(),
                                            ::testing::Bool()),
                         [](const auto& info) {
                           return std::string(std::get<0>(info.param) ? "Lines" : "Points") +
                                  (std::get<1>(info.param) ? "Rig" : "Single") +
                                  (std::get<2>(info.param) ? "Sim3" : "SE3");
                         });

// The same correspondences against lines through their points, with random
// directions.
PoseData LinesThroughPoints(const PoseData& points, std::mt19937_64& rng) {
  PoseData d = points;
  d.points.clear();
  for (const Eigen::Vector3d& x : points.points) {
    d.lines.push_back(PluckerLine::FromPointAndDirection(x, RandomUnit(rng)));
  }
  return d;
}

// Monte Carlo: least-squares refinement from the truth on observations with
// σ px of Gaussian noise; the RMS rotation error should attain the
// Cramér–Rao bound (the refinement is efficient) and lines should cost about
// √2 over points (one residual per correspondence instead of two).
TEST(RotationErrorBound, IsAttainedByTheRefinementForPointsAndLines) {
  for (const bool rig : {false, true}) {
    std::mt19937_64 rng(rig ? 31 : 17);
    const Sim3d truth = RandomPose(rng, false);
    const PoseData points = RandomPoseData(false, rig, truth, rng);
    const PoseData lines = LinesThroughPoints(points, rng);
    std::vector<int> all(points.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    constexpr double kSigma = 1.0;
    double bound[2], rms[2];
    for (int kind = 0; kind < 2; ++kind) {
      const PoseData& exact = kind == 0 ? points : lines;
      bound[kind] = RotationErrorBound(exact, all, truth, kSigma, false);
      ASSERT_TRUE(std::isfinite(bound[kind]));
      RefineOptions options;
      options.loss_scale = 1e4;  // least squares: the bound is for Gaussian noise
      options.function_tolerance = 1e-12;
      std::normal_distribution<double> noise(0.0, kSigma);
      double sum = 0;
      constexpr int kTrials = 400;
      for (int trial = 0; trial < kTrials; ++trial) {
        PoseData noisy = exact;
        for (size_t i = 0; i < noisy.size(); ++i) {
          noisy.normalized[i] += Eigen::Vector2d(noise(rng), noise(rng)) / noisy.focal[i];
        }
        Sim3d pose = truth;
        RefinePose(noisy, all, options, &pose);
        const double angle = pose.rotation.angularDistance(truth.rotation);
        sum += angle * angle;
      }
      rms[kind] = std::sqrt(sum / kTrials);
      // 400 trials of a 3-D error: the RMS is known to ~3 % (one σ).
      EXPECT_NEAR(rms[kind] / bound[kind], 1.0, 0.12)
          << (kind ? "lines" : "points") << (rig ? ", rig" : ", single");
    }
    // F_line = Σ Jᵀ n nᵀ J ⪯ F_point: a line never informs more than its point.
    EXPECT_GT(bound[1], bound[0]);
    EXPECT_GT(bound[1] / bound[0], 1.2) << "random directions: about √2";
    EXPECT_LT(bound[1] / bound[0], 1.7) << "random directions: about √2";
  }
}

TEST(RotationErrorBound, IsInfiniteWithoutEnoughInformation) {
  std::mt19937_64 rng(5);
  const Sim3d truth = RandomPose(rng, false);
  const PoseData points = RandomPoseData(false, false, truth, rng);
  const std::vector<int> two = {0, 1};  // 4 residuals for 6 parameters
  EXPECT_TRUE(std::isinf(RotationErrorBound(points, two, truth, 1.0, false)));
  std::vector<int> all(points.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  const double one_px = RotationErrorBound(points, all, truth, 1.0, false);
  // One camera at the rig origin cannot see a scale, but that gauge does not
  // touch the rotation: its bound is the rigid one ([guard] #17; it was +inf).
  EXPECT_NEAR(RotationErrorBound(points, all, truth, 1.0, true), one_px, 1e-6 * one_px);
  EXPECT_NEAR(RotationErrorBound(points, all, truth, 2.5, false), 2.5 * one_px, 1e-12 * one_px);
}

TEST(RefinePose, RejectsBadOptions) {
  RefineOptions options;
  options.loss_scale = 0;
  EXPECT_THROW(options.Check(), Error);
}

}  // namespace
}  // namespace linecloud
