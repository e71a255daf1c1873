#include "linecloud/geometry/camera.h"

#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "linecloud/testing/test_util.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// Realistic cameras of every supported model (values like COLMAP's on
// phone and action-camera images).
std::vector<Camera> RealisticCameras() {
  const auto make = [](CameraModelId id, std::vector<double> params) {
    Camera c;
    c.camera_id = static_cast<uint32_t>(id) + 1;
    c.model_id = id;
    c.width = 1536;
    c.height = 1024;
    c.params = std::move(params);
    return c;
  };
  return {
      make(CameraModelId::kSimplePinhole, {1200, 768, 512}),
      make(CameraModelId::kPinhole, {1200, 1190, 770, 510}),
      make(CameraModelId::kSimpleRadial, {1200, 768, 512, -0.08}),
      make(CameraModelId::kRadial, {1200, 768, 512, -0.1, 0.02}),
      make(CameraModelId::kOpenCV, {1200, 1190, 770, 510, -0.12, 0.03, 1e-3, -5e-4}),
      make(CameraModelId::kOpenCVFisheye, {600, 600, 768, 512, 0.05, -0.01, 0.002, -0.0005}),
      make(CameraModelId::kFullOpenCV,
           {1200, 1190, 770, 510, -0.12, 0.03, 1e-3, -5e-4, 0.004, 0.01, 0.002, 0.0005}),
  };
}

TEST(Camera, NamesAndParameterCounts) {
  EXPECT_EQ(CameraModelName(CameraModelId::kOpenCVFisheye), "OPENCV_FISHEYE");
  EXPECT_EQ(CameraModelFromName("FULL_OPENCV"), CameraModelId::kFullOpenCV);
  EXPECT_EQ(CameraModelFromName("FOV"), CameraModelId::kInvalid);
  EXPECT_EQ(CameraModelFromInt(4), CameraModelId::kOpenCV);
  EXPECT_EQ(CameraModelFromInt(7), CameraModelId::kInvalid);
  EXPECT_EQ(CameraModelNumParams(CameraModelId::kFullOpenCV), 12);
  EXPECT_EQ(CameraModelNumParams(CameraModelId::kSimplePinhole), 3);
}

TEST(Camera, PixelRoundTripEveryModel) {
  for (const Camera& camera : RealisticCameras()) {
    SCOPED_TRACE(std::string(CameraModelName(camera.model_id)));
    camera.Check("test");
    double worst = 0;
    for (double x = 0.5; x < camera.width; x += 48.0) {
      for (double y = 0.5; y < camera.height; y += 48.0) {
        const Eigen::Vector2d xy(x, y);
        const Eigen::Vector3d ray = camera.CamFromImg(xy);
        ASSERT_TRUE(ray.allFinite());
        worst = std::max(worst, (camera.ImgFromCam(ray) - xy).norm());
      }
    }
    EXPECT_LT(worst, 1e-9) << "pixel -> ray -> pixel";
  }
}

TEST(Camera, PointRoundTripEveryModel) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-0.5, 0.5);
  for (const Camera& camera : RealisticCameras()) {
    SCOPED_TRACE(std::string(CameraModelName(camera.model_id)));
    for (int i = 0; i < 1000; ++i) {
      const Eigen::Vector3d x(u(rng), u(rng), 1.0);  // within the field of view
      const Eigen::Vector3d back = camera.CamFromImg(camera.ImgFromCam(3.0 * x));
      EXPECT_LT((back - x).norm(), 1e-10);
      EXPECT_LT((camera.BearingFromImg(camera.ImgFromCam(x)) - x.normalized()).norm(), 1e-10);
    }
  }
}

TEST(Camera, PinholeMatchesTheFormula) {
  Camera c;
  c.model_id = CameraModelId::kPinhole;
  c.width = 640;
  c.height = 480;
  c.params = {500, 510, 320.5, 240.5};
  const Eigen::Vector2d xy = c.ImgFromCam(Eigen::Vector3d(0.2, -0.1, 2.0));
  EXPECT_NEAR(xy.x(), 500 * 0.1 + 320.5, 1e-12);
  EXPECT_NEAR(xy.y(), 510 * -0.05 + 240.5, 1e-12);
}

TEST(Camera, CheckRejectsBadCameras) {
  Camera c = RealisticCameras()[1];
  c.params.pop_back();
  EXPECT_THROW(c.Check("cams.txt"), Error);
  try {
    c.Check("cams.txt");
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cams.txt"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("takes 4 parameters"), std::string::npos);
  }
  c = RealisticCameras()[1];
  c.params[2] = std::nan("");
  EXPECT_THROW(c.Check("x"), Error);
  c = RealisticCameras()[1];
  c.params[0] = -3;
  EXPECT_THROW(c.Check("x"), Error);
  c.model_id = CameraModelId::kInvalid;
  EXPECT_THROW(c.Check("x"), Error);
}

// [harden] 5: SIMPLE_RADIAL k = 1e12 used to be undistorted into a 0.01°
// field of view and localized with "success": true.
TEST(Camera, CheckRejectsImplausibleDistortion) {
  for (const Camera& c : RealisticCameras())
    EXPECT_NO_THROW(c.Check("cams.txt")) << CameraModelName(c.model_id);
  Camera c = RealisticCameras()[2];  // SIMPLE_RADIAL
  c.params[3] = 1e12;
  EXPECT_NE(testing::ErrorOf([&] { c.Check("cams.txt"); }).find("physically implausible"),
            std::string::npos);
  // Strong barrel distortion folds the border back (r (1 + k r²) peaks inside).
  c.params[3] = -1.5;
  EXPECT_NE(testing::ErrorOf([&] { c.Check("cams.txt"); }).find("camera 3"), std::string::npos);
  c = RealisticCameras()[4];  // OPENCV
  c.params[4] = -3;
  EXPECT_THROW(c.Check("cams.txt"), Error);
}

TEST(Camera, DistortionJacobianMatchesTheFormula) {
  // SIMPLE_RADIAL: D(x) = x (1 + k |x|²), ∂D/∂x = (1 + k |x|²) I + 2k x xᵀ.
  const Camera c = RealisticCameras()[2];
  const double k = c.params[3];
  const Eigen::Vector2d x(0.4, -0.3);
  const Eigen::Matrix2d expected =
      (1 + k * x.squaredNorm()) * Eigen::Matrix2d::Identity() + 2 * k * x * x.transpose();
  EXPECT_LT((DistortionJacobian(c.model_id, c.params, x) - expected).norm(), 1e-8);
}

TEST(Camera, CanUndistortStopsAtTheFold) {
  for (const Camera& c : RealisticCameras()) {
    EXPECT_TRUE(c.CanUndistort({0, 0})) << CameraModelName(c.model_id);
    EXPECT_TRUE(c.CanUndistort({1536, 1024})) << CameraModelName(c.model_id);
    EXPECT_FALSE(c.CanUndistort({std::nan(""), 3})) << CameraModelName(c.model_id);
  }
  // SIMPLE_RADIAL k = −0.08, f = 1200: the distorted radius r (1 + k r²) peaks
  // at r = 1/√(3|k|), 1.36 normalised (1633 px from the centre); beyond it no
  // ray maps to the pixel.
  const Camera c = RealisticCameras()[2];
  EXPECT_TRUE(c.CanUndistort({768 + 1500, 512}));
  EXPECT_FALSE(c.CanUndistort({768 + 1800, 512}));
  EXPECT_FALSE(c.CanUndistort({768 - 4000, 512 + 3000}));
  // No distortion: every finite pixel has a ray.
  EXPECT_TRUE(RealisticCameras()[0].CanUndistort({1e6, -1e6}));
}

}  // namespace
}  // namespace linecloud
