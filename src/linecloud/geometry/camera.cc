#include "linecloud/geometry/camera.h"

#include <array>
#include <cmath>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

struct ModelInfo {
  CameraModelId id;
  std::string_view name;
  int num_params;
  bool single_focal;  // f instead of fx, fy
};

constexpr std::array<ModelInfo, 7> kModels = {{
    {CameraModelId::kSimplePinhole, "SIMPLE_PINHOLE", 3, true},
    {CameraModelId::kPinhole, "PINHOLE", 4, false},
    {CameraModelId::kSimpleRadial, "SIMPLE_RADIAL", 4, true},
    {CameraModelId::kRadial, "RADIAL", 5, true},
    {CameraModelId::kOpenCV, "OPENCV", 8, false},
    {CameraModelId::kOpenCVFisheye, "OPENCV_FISHEYE", 8, false},
    {CameraModelId::kFullOpenCV, "FULL_OPENCV", 12, false},
}};

const ModelInfo* FindModel(CameraModelId id) {
  for (const ModelInfo& m : kModels) {
    if (m.id == id) return &m;
  }
  return nullptr;
}

const ModelInfo& ModelOrThrow(CameraModelId id) {
  const ModelInfo* m = FindModel(id);
  if (m == nullptr) Fail("unsupported camera model id {}", static_cast<int>(id));
  return *m;
}

// Index of the first distortion parameter.
int DistortionOffset(CameraModelId id) { return ModelOrThrow(id).single_focal ? 3 : 4; }

}  // namespace

std::string_view CameraModelName(CameraModelId model_id) {
  const ModelInfo* m = FindModel(model_id);
  return m ? m->name : std::string_view("INVALID");
}

CameraModelId CameraModelFromName(std::string_view name) {
  for (const ModelInfo& m : kModels) {
    if (m.name == name) return m.id;
  }
  return CameraModelId::kInvalid;
}

CameraModelId CameraModelFromInt(int model_id) {
  const ModelInfo* m = FindModel(static_cast<CameraModelId>(model_id));
  return m ? m->id : CameraModelId::kInvalid;
}

int CameraModelNumParams(CameraModelId model_id) {
  const ModelInfo* m = FindModel(model_id);
  return m ? m->num_params : -1;
}

void Camera::Check(std::string_view source) const {
  const ModelInfo* m = FindModel(model_id);
  if (m == nullptr) {
    Fail(
        "{}: camera {}: unsupported camera model (id {}); supported: "
        "SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV, "
        "OPENCV_FISHEYE, FULL_OPENCV",
        source, camera_id, static_cast<int>(model_id));
  }
  if (static_cast<int>(params.size()) != m->num_params) {
    Fail("{}: camera {}: model {} takes {} parameters, got {}", source, camera_id, m->name,
         m->num_params, params.size());
  }
  for (size_t i = 0; i < params.size(); ++i) {
    if (!std::isfinite(params[i])) {
      Fail("{}: camera {}: parameter {} is not finite", source, camera_id, i);
    }
  }
  if (!(FocalLengthX() > 0) || !(FocalLengthY() > 0)) {
    Fail("{}: camera {}: focal length must be positive", source, camera_id);
  }
  if (width == 0 || height == 0) {
    Fail("{}: camera {}: width and height must be positive", source, camera_id);
  }
  CheckDistortion(source);
}

// Walks from the principal point to the image's corners and edge midpoints:
// undistortion must converge (the pixel comes back within 0.01 px), the
// undistorted radius must grow along each walk (no fold: two pixels never see
// one ray), and, except for the fisheye model (whose undistorted radius tan θ
// grows without bound), the border must keep its radius within a factor 5 —
// SIMPLE_RADIAL k = 1e12 shrinks a 60° field of view to 0.01°.
void Camera::CheckDistortion(std::string_view source) const {
  if (model_id == CameraModelId::kSimplePinhole || model_id == CameraModelId::kPinhole) return;
  constexpr int kSteps = 24;
  constexpr double kMaxRadiusFactor = 5;
  const Eigen::Vector2d c = PrincipalPoint();
  const double w = static_cast<double>(width), h = static_cast<double>(height);
  const Eigen::Vector2d ends[] = {{0, 0},     {w, 0},     {0, h},     {w, h},
                                  {w / 2, 0}, {w / 2, h}, {0, h / 2}, {w, h / 2}};
  const Eigen::Vector2d f(FocalLengthX(), FocalLengthY());
  for (const Eigen::Vector2d& end : ends) {
    if ((end - c).norm() < 1) continue;  // the principal point on the border
    double last_radius = 0;
    for (int s = 1; s <= kSteps; ++s) {
      const Eigen::Vector2d xy = c + (end - c) * (static_cast<double>(s) / kSteps);
      const Eigen::Vector2d distorted = (xy - c).cwiseQuotient(f);
      const Eigen::Vector2d undistorted = UndistortNormalized(model_id, params, distorted);
      const Eigen::Vector2d back =
          DistortNormalized(model_id, params, undistorted).cwiseProduct(f) + c;
      if (!undistorted.allFinite() || !((back - xy).norm() < 0.01)) {
        Fail(
            "{}: camera {}: the {} distortion cannot be undone at pixel ({:.1f}, {:.1f}) "
            "(parameters implausible for a {}x{} image)",
            source, camera_id, CameraModelName(model_id), xy.x(), xy.y(), width, height);
      }
      const double radius = undistorted.norm();
      if (!(radius > last_radius)) {
        Fail(
            "{}: camera {}: the {} distortion folds the image over itself near pixel "
            "({:.1f}, {:.1f}) (two pixels would see one ray)",
            source, camera_id, CameraModelName(model_id), xy.x(), xy.y());
      }
      last_radius = radius;
      const double factor = radius / distorted.norm();
      if (s == kSteps && model_id != CameraModelId::kOpenCVFisheye &&
          !(factor < kMaxRadiusFactor && factor > 1 / kMaxRadiusFactor)) {
        Fail(
            "{}: camera {}: the {} distortion scales the image border's radius by {:.3g} "
            "(physically implausible; at most {} either way)",
            source, camera_id, CameraModelName(model_id), factor, kMaxRadiusFactor);
      }
    }
  }
}

double Camera::FocalLengthX() const { return params.at(0); }
double Camera::FocalLengthY() const {
  return ModelOrThrow(model_id).single_focal ? params.at(0) : params.at(1);
}
void Camera::ScaleFocalLength(double factor) {
  params.at(0) *= factor;
  if (!ModelOrThrow(model_id).single_focal) params.at(1) *= factor;
}

void Camera::ScaleFocalLengthY(double factor) {
  if (!ModelOrThrow(model_id).single_focal) params.at(1) *= factor;
}

void Camera::AddRadialDistortion(double dk1) {
  if (model_id == CameraModelId::kPinhole) {
    model_id = CameraModelId::kOpenCV;
    params.resize(8, 0.0);
  } else if (model_id == CameraModelId::kSimplePinhole) {
    model_id = CameraModelId::kSimpleRadial;
    params.resize(4, 0.0);
  }
  params.at(static_cast<size_t>(DistortionOffset(model_id))) += dk1;
}

void Camera::ShiftPrincipalPoint(double dx, double dy) {
  const size_t i = ModelOrThrow(model_id).single_focal ? 1 : 2;
  params.at(i) += dx;
  params.at(i + 1) += dy;
}

Eigen::Vector2d Camera::PrincipalPoint() const {
  const int i = ModelOrThrow(model_id).single_focal ? 1 : 2;
  return Eigen::Vector2d(params.at(i), params.at(i + 1));
}

Eigen::Vector2d DistortNormalized(CameraModelId model_id, const std::vector<double>& params,
                                  const Eigen::Vector2d& p) {
  const double* k = params.data() + DistortionOffset(model_id);
  const double u = p.x(), v = p.y();
  const double u2 = u * u, v2 = v * v, uv = u * v, r2 = u2 + v2;
  switch (model_id) {
    case CameraModelId::kSimplePinhole:
    case CameraModelId::kPinhole:
      return p;
    case CameraModelId::kSimpleRadial:
      return p * (1.0 + k[0] * r2);
    case CameraModelId::kRadial:
      return p * (1.0 + k[0] * r2 + k[1] * r2 * r2);
    case CameraModelId::kOpenCV: {
      const double radial = 1.0 + k[0] * r2 + k[1] * r2 * r2;
      return {u * radial + 2.0 * k[2] * uv + k[3] * (r2 + 2.0 * u2),
              v * radial + 2.0 * k[3] * uv + k[2] * (r2 + 2.0 * v2)};
    }
    case CameraModelId::kOpenCVFisheye: {
      const double r = std::sqrt(r2);
      if (r < 1e-12) return p;
      const double theta = std::atan(r);
      const double t2 = theta * theta;
      const double theta_d = theta * (1.0 + t2 * (k[0] + t2 * (k[1] + t2 * (k[2] + t2 * k[3]))));
      return p * (theta_d / r);
    }
    case CameraModelId::kFullOpenCV: {
      const double r4 = r2 * r2, r6 = r4 * r2;
      const double radial =
          (1.0 + k[0] * r2 + k[1] * r4 + k[4] * r6) / (1.0 + k[5] * r2 + k[6] * r4 + k[7] * r6);
      return {u * radial + 2.0 * k[2] * uv + k[3] * (r2 + 2.0 * u2),
              v * radial + 2.0 * k[3] * uv + k[2] * (r2 + 2.0 * v2)};
    }
    case CameraModelId::kInvalid:
      break;
  }
  Fail("unsupported camera model id {}", static_cast<int>(model_id));
}

Eigen::Matrix2d DistortionJacobian(CameraModelId model_id, const std::vector<double>& params,
                                   const Eigen::Vector2d& x) {
  const double h = 1e-7 * std::max(1.0, x.norm());
  Eigen::Matrix2d jacobian;
  for (int d = 0; d < 2; ++d) {
    Eigen::Vector2d dx = Eigen::Vector2d::Zero();
    dx[d] = h;
    jacobian.col(d) = (DistortNormalized(model_id, params, x + dx) -
                       DistortNormalized(model_id, params, x - dx)) /
                      (2.0 * h);
  }
  return jacobian;
}

// Newton's method on D(x) = x_d with a central-difference Jacobian. Converges
// in a few iterations for the mild-to-strong distortions found in practice.
Eigen::Vector2d UndistortNormalized(CameraModelId model_id, const std::vector<double>& params,
                                    const Eigen::Vector2d& distorted) {
  if (model_id == CameraModelId::kSimplePinhole || model_id == CameraModelId::kPinhole) {
    return distorted;
  }
  constexpr int kMaxIterations = 100;
  constexpr double kStepTolerance = 1e-15;
  Eigen::Vector2d x = distorted;
  for (int iter = 0; iter < kMaxIterations; ++iter) {
    const Eigen::Matrix2d jacobian = DistortionJacobian(model_id, params, x);
    const Eigen::Vector2d residual = DistortNormalized(model_id, params, x) - distorted;
    const Eigen::Vector2d step = jacobian.partialPivLu().solve(residual);
    if (!step.allFinite()) break;
    x -= step;
    if (step.squaredNorm() < kStepTolerance * kStepTolerance * std::max(1.0, x.squaredNorm())) {
      break;
    }
  }
  return x;
}

Eigen::Vector2d Camera::ImgFromCam(const Eigen::Vector3d& point_in_cam) const {
  const Eigen::Vector2d normalized = point_in_cam.hnormalized();
  const Eigen::Vector2d d = DistortNormalized(model_id, params, normalized);
  const Eigen::Vector2d c = PrincipalPoint();
  return {FocalLengthX() * d.x() + c.x(), FocalLengthY() * d.y() + c.y()};
}

bool Camera::CanUndistort(const Eigen::Vector2d& xy) const {
  if (!xy.allFinite()) return false;
  if (model_id == CameraModelId::kSimplePinhole || model_id == CameraModelId::kPinhole) return true;
  const Eigen::Vector3d ray = CamFromImg(xy);
  if (!ray.allFinite() || !(ray.z() > 0)) return false;
  if (!((ImgFromCam(ray) - xy).norm() < 0.01)) return false;
  const Eigen::Vector2d undistorted = ray.head<2>() / ray.z();
  const Eigen::Vector2d distorted = DistortNormalized(model_id, params, undistorted);
  if (distorted.dot(undistorted) < 0) return false;
  const Eigen::Matrix2d jacobian = DistortionJacobian(model_id, params, undistorted);
  return jacobian.determinant() > 0 && jacobian.trace() > 0;
}

Eigen::Vector3d Camera::CamFromImg(const Eigen::Vector2d& xy) const {
  const Eigen::Vector2d c = PrincipalPoint();
  const Eigen::Vector2d d((xy.x() - c.x()) / FocalLengthX(), (xy.y() - c.y()) / FocalLengthY());
  return UndistortNormalized(model_id, params, d).homogeneous();
}

}  // namespace linecloud
