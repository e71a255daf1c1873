#include "linecloud/estimation/local_scale.h"

#include <random>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

namespace linecloud {
namespace {

// A camera offset from the rig origin, local points in the rig frame at the
// true scale, and the map as points or as lines through them.
struct OneCamera {
  PoseData data;
  Sim3d truth;
};

OneCamera MakeOneCamera(bool lines, std::mt19937_64& rng) {
  std::normal_distribution<double> g;
  OneCamera c;
  c.truth =
      Sim3d(2.5, Eigen::Quaterniond(Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized())),
            Eigen::Vector3d(0.5, -1, 2));
  c.data.cam_from_rig = {
      Rigid3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(0.4, 0.1, -0.2))};
  const Sim3d world_from_rig = c.truth.Inverse();
  for (int i = 0; i < 20; ++i) {
    const Eigen::Vector3d x_cam(g(rng), g(rng), 5 + g(rng));
    const Eigen::Vector3d x_rig = c.data.cam_from_rig[0].Inverse() * x_cam;
    const Eigen::Vector3d x_world = world_from_rig * x_rig;
    c.data.camera.push_back(0);
    c.data.normalized.push_back(x_cam.head<2>() / x_cam.z());
    c.data.focal.push_back(500);
    c.data.bearings.push_back(x_cam.normalized());
    c.data.points_local.push_back(x_rig);
    if (lines) {
      c.data.lines.push_back(
          PluckerLine::FromPointAndDirection(x_world, Eigen::Vector3d(g(rng), g(rng), g(rng))));
    } else {
      c.data.points.push_back(x_world);
    }
  }
  return c;
}

// The scale is recovered exactly from exact local points, whatever scale the
// pose had, and the camera's pose in the world does not move.
TEST(LocalScale, ExactLocalPointsGiveTheScaleAndKeepTheCamera) {
  std::mt19937_64 rng(3);
  for (const bool lines : {false, true}) {
    const OneCamera c = MakeOneCamera(lines, rng);
    std::vector<int> all(c.data.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
    for (size_t i = 0; i < all.size(); ++i) {
      EXPECT_LT(LocalPointResidual(c.data, all[i], c.truth).norm(), 1e-12);
    }
    // The same camera pose under a wrong scale: the rig origin moved about
    // the camera.
    const Eigen::Vector3d centre_rig = c.data.cam_from_rig[0].Inverse().translation;
    const Eigen::Vector3d camera_world = c.truth.Inverse() * centre_rig;
    const double wrong = 0.7 * c.truth.scale;
    Sim3d pose(wrong, c.truth.rotation, centre_rig - wrong * (c.truth.rotation * camera_world));
    ASSERT_TRUE(SeenByOneCamera(c.data, all));
    const std::optional<LocalScaleFit> fit = FitScaleToLocalPoints(c.data, all, &pose);
    ASSERT_TRUE(fit.has_value());
    EXPECT_NEAR(fit->scale_before, wrong, 1e-12);
    EXPECT_NEAR(pose.scale, c.truth.scale, 1e-9) << (lines ? "lines" : "points");
    EXPECT_NEAR((pose.translation - c.truth.translation).norm(), 0, 1e-9);
    EXPECT_NEAR((pose.Inverse() * centre_rig - camera_world).norm(), 0, 1e-9);
    EXPECT_LT(fit->sigma_local, 1e-9);
  }
}

// Noise on the local points: the reported standard error of log s matches
// the spread of the estimates over many draws (within 25 %).
TEST(LocalScale, TheStandardErrorMatchesTheSpread) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> g;
  for (const bool lines : {false, true}) {
    double sum_sq = 0, sum_se2 = 0;
    const int draws = 400;
    for (int k = 0; k < draws; ++k) {
      OneCamera c = MakeOneCamera(lines, rng);
      for (Eigen::Vector3d& x : c.data.points_local)
        x += 0.02 * Eigen::Vector3d(g(rng), g(rng), g(rng));
      std::vector<int> all(c.data.size());
      for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
      Sim3d pose = c.truth;
      const std::optional<LocalScaleFit> fit = FitScaleToLocalPoints(c.data, all, &pose);
      ASSERT_TRUE(fit.has_value());
      const double e = std::log(pose.scale / c.truth.scale);
      sum_sq += e * e;
      sum_se2 += fit->log_scale_se * fit->log_scale_se;
    }
    EXPECT_NEAR(std::sqrt(sum_sq / sum_se2), 1.0, 0.25) << (lines ? "lines" : "points");
  }
}

// Two cameras, or too little data: no fit, the pose untouched.
TEST(LocalScale, NothingToFitLeavesThePose) {
  std::mt19937_64 rng(9);
  OneCamera c = MakeOneCamera(false, rng);
  c.data.cam_from_rig.push_back(Rigid3d());
  c.data.camera[1] = 1;
  EXPECT_FALSE(SeenByOneCamera(c.data, std::vector<int>{0, 1}));
  Sim3d pose = c.truth;
  EXPECT_FALSE(FitScaleToLocalPoints(c.data, std::vector<int>{0}, &pose).has_value());
  PoseData no_local = c.data;
  no_local.points_local.clear();
  EXPECT_FALSE(FitScaleToLocalPoints(no_local, std::vector<int>{0, 2, 3}, &pose).has_value());
  EXPECT_EQ(pose.scale, c.truth.scale);
}

}  // namespace
}  // namespace linecloud
