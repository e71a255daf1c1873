// COLMAP camera models with projection and unprojection, following COLMAP's
// definitions and parameter orders (model ids are COLMAP's, so binary models
// and databases interoperate). Pixel convention: the centre of the top-left
// pixel is (0.5, 0.5).
//
//   SIMPLE_PINHOLE  f, cx, cy
//   PINHOLE         fx, fy, cx, cy
//   SIMPLE_RADIAL   f, cx, cy, k
//   RADIAL          f, cx, cy, k1, k2
//   OPENCV          fx, fy, cx, cy, k1, k2, p1, p2
//   OPENCV_FISHEYE  fx, fy, cx, cy, k1, k2, k3, k4
//   FULL_OPENCV     fx, fy, cx, cy, k1, k2, p1, p2, k3, k4, k5, k6
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

namespace linecloud {

enum class CameraModelId : int {
  kInvalid = -1,
  kSimplePinhole = 0,
  kPinhole = 1,
  kSimpleRadial = 2,
  kRadial = 3,
  kOpenCV = 4,
  kOpenCVFisheye = 5,
  kFullOpenCV = 6,
};

// "PINHOLE" etc.; "INVALID" for unknown ids.
std::string_view CameraModelName(CameraModelId model_id);
// kInvalid for unknown names.
CameraModelId CameraModelFromName(std::string_view name);
// kInvalid for ids that linecloud does not support.
CameraModelId CameraModelFromInt(int model_id);
// Number of parameters; -1 for kInvalid.
int CameraModelNumParams(CameraModelId model_id);

struct Camera {
  uint32_t camera_id = 0;
  CameraModelId model_id = CameraModelId::kInvalid;
  uint64_t width = 0;
  uint64_t height = 0;
  std::vector<double> params;

  // Throws Error naming `source` and the camera when the model is unknown, the
  // number of parameters is wrong, a parameter is not finite, or a focal
  // length is not positive.
  // Also throws when the distortion is physically implausible over the image
  // (CheckDistortion).
  void Check(std::string_view source) const;
  void CheckDistortion(std::string_view source) const;

  double FocalLengthX() const;
  double FocalLengthY() const;
  double MeanFocalLength() const { return 0.5 * (FocalLengthX() + FocalLengthY()); }
  Eigen::Vector2d PrincipalPoint() const;
  // Multiplies the focal length(s) by `factor`.
  void ScaleFocalLength(double factor);
  // Moves the principal point by (dx, dy) pixels.
  void ShiftPrincipalPoint(double dx, double dy);
  // Multiplies fy alone (models with fx and fy; others unchanged).
  void ScaleFocalLengthY(double factor);
  // Adds dk1 to the first radial distortion coefficient; a PINHOLE camera
  // becomes the OPENCV camera with that k1 (the other coefficients 0), a
  // SIMPLE_PINHOLE one the SIMPLE_RADIAL camera.
  void AddRadialDistortion(double dk1);

  // Projects a point in the camera frame (z > 0) to pixel coordinates.
  Eigen::Vector2d ImgFromCam(const Eigen::Vector3d& point_in_cam) const;

  // Unprojects pixel coordinates to the normalised image plane (z = 1),
  // removing distortion iteratively.
  Eigen::Vector3d CamFromImg(const Eigen::Vector2d& xy) const;

  // Whether the pixel's ray can be recovered: undistortion converges (the
  // pixel comes back within 0.01 px), the ray is in front, and the pixel lies
  // before the distortion's fold (same side of the centre, Jacobian keeps its
  // orientation). Polynomial models fold beyond some radius (SIMPLE_RADIAL
  // with k < 0 peaks and falls). Always true without distortion.
  bool CanUndistort(const Eigen::Vector2d& xy) const;

  // Unit bearing vector of a pixel.
  Eigen::Vector3d BearingFromImg(const Eigen::Vector2d& xy) const {
    return CamFromImg(xy).normalized();
  }
};

// Distortion on normalised coordinates (exposed for tests): maps an ideal
// normalised point to its distorted position, for the model's extra params.
Eigen::Vector2d DistortNormalized(CameraModelId model_id, const std::vector<double>& params,
                                  const Eigen::Vector2d& undistorted);
Eigen::Vector2d UndistortNormalized(CameraModelId model_id, const std::vector<double>& params,
                                    const Eigen::Vector2d& distorted);
// ∂D/∂x of DistortNormalized at x (central differences).
Eigen::Matrix2d DistortionJacobian(CameraModelId model_id, const std::vector<double>& params,
                                   const Eigen::Vector2d& x);

}  // namespace linecloud
