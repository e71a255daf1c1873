#include "linecloud/estimation/pose_data.h"

#include <cmath>
#include <vector>

#include <gtest/gtest.h>

#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// One camera at the origin looking down +z, focal 100 px, every observation
// at the image centre.
PoseData CentreObservations(size_t n) {
  PoseData d;
  d.cam_from_rig = {Rigid3d()};
  d.camera.assign(n, 0);
  d.normalized.assign(n, Eigen::Vector2d::Zero());
  d.focal.assign(n, 100.0);
  d.bearings.assign(n, Eigen::Vector3d::UnitZ());
  return d;
}

// A mean reprojection error is finite: a correspondence the pose puts behind
// its camera has no image position and is left out, for points and for lines
// (CI once wrote a null refined reprojection error into an eval report when
// a RANSAC inlier fell behind the camera after refinement).
TEST(MeanReprojectionError, LeavesOutWhatThePosePutsBehindItsCamera) {
  PoseData points = CentreObservations(3);
  points.points = {{0.03, 0.04, 1.0}, {0.0, -0.01, 1.0}, {0.0, 0.0, -2.0}};
  const Sim3d identity;
  // 5 px and 1 px; the third point is behind the camera.
  EXPECT_NEAR(MeanReprojectionError(points, identity, std::vector<int>{0, 1, 2}), 3.0, 1e-12);
  EXPECT_NEAR(MeanReprojectionError(points, identity, std::vector<int>{0}), 5.0, 1e-12);
  EXPECT_EQ(MeanReprojectionError(points, identity, std::vector<int>{2}), 0.0);
  EXPECT_EQ(MeanReprojectionError(points, identity, std::vector<int>{}), 0.0);
  // Moved 3 units back, the third point is in front and counts: (5 + 1 + 0)/3
  // scaled by the new depths.
  const Sim3d back(1.0, Eigen::Quaterniond::Identity(), Eigen::Vector3d(0, 0, 3));
  EXPECT_NEAR(MeanReprojectionError(points, back, std::vector<int>{0, 1, 2}),
              (5.0 / 4 + 1.0 / 4 + 0.0) / 3, 1e-12);

  // Lines along x: one 0.1 above the optical axis at depth 5 (its image is the
  // row 2 px above the centre), one through the axis behind the camera (its
  // image passes through the centre, but behind the camera).
  PoseData lines = CentreObservations(2);
  lines.lines = {PluckerLine::FromPointAndDirection({0, 0.1, 5}, Eigen::Vector3d::UnitX()),
                 PluckerLine::FromPointAndDirection({0, 0, -5}, Eigen::Vector3d::UnitX())};
  EXPECT_NEAR(MeanReprojectionError(lines, identity, std::vector<int>{0, 1}), 2.0, 1e-12);
  EXPECT_FALSE(std::isfinite(SquaredReprojectionError(lines, CameraPoses(lines, identity), 1)));
  EXPECT_NE(testing::ErrorOf([&] {
              MeanReprojectionError(lines, identity, std::vector<int>{0, 2});
            }).find("MeanReprojectionError: correspondence index 2 out of range"),
            std::string::npos);
}

}  // namespace
}  // namespace linecloud
