// COLMAP sparse models (cameras, images, points3D; rigs and frames of COLMAP
// >= 3.12 when present) in COLMAP's binary and text formats.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

inline constexpr uint64_t kInvalidPoint3DId = std::numeric_limits<uint64_t>::max();

struct Point2D {
  Eigen::Vector2d xy = Eigen::Vector2d::Zero();
  uint64_t point3D_id = kInvalidPoint3DId;
};

struct Image {
  uint32_t image_id = 0;
  uint32_t camera_id = 0;
  std::string name;
  Rigid3d cam_from_world;
  std::vector<Point2D> points2D;
};

struct TrackElement {
  uint32_t image_id = 0;
  uint32_t point2D_idx = 0;
};

struct Point3D {
  Eigen::Vector3d xyz = Eigen::Vector3d::Zero();
  std::array<uint8_t, 3> color = {0, 0, 0};
  double error = -1.0;
  std::vector<TrackElement> track;
};

// COLMAP >= 3.12 sensor rigs (binary rigs.bin / frames.bin).
struct SensorId {
  int type = 0;  // 0 = camera, 1 = IMU
  uint32_t id = 0;
};
struct RigSensor {
  SensorId sensor;
  std::optional<Rigid3d> sensor_from_rig;
};
struct Rig {
  uint32_t rig_id = 0;
  std::optional<SensorId> ref_sensor;
  std::vector<RigSensor> sensors;  // without the reference sensor
};
struct FrameData {
  SensorId sensor;
  uint64_t data_id = 0;
};
struct Frame {
  uint32_t frame_id = 0;
  uint32_t rig_id = 0;
  Rigid3d rig_from_world;
  std::vector<FrameData> data;
};

struct Reconstruction {
  std::map<uint32_t, Camera> cameras;
  std::map<uint32_t, Image> images;
  std::unordered_map<uint64_t, Point3D> points3D;
  std::map<uint32_t, Rig> rigs;
  std::map<uint32_t, Frame> frames;

  std::vector<uint64_t> SortedPoint3DIds() const;
  double MeanTrackLength() const;
  // Throws Error naming `source` on dangling references (image → camera,
  // track → image / point2D index) and non-finite coordinates.
  void Check(std::string_view source) const;
};

// The coordinates of the model's points `ids` (each must exist).
std::vector<Eigen::Vector3d> PointCoordinates(const Reconstruction& model,
                                              std::span<const uint64_t> ids);

enum class ModelFormat { kBinary, kText };

// Reads a model folder; binary files win when both forms are present.
Reconstruction ReadColmapModel(const std::string& dir);
// Writes cameras, images, points3D (and rigs/frames when present and binary).
void WriteColmapModel(const Reconstruction& reconstruction, const std::string& dir,
                      ModelFormat format);

// Parsers over in-memory file contents; `source` names the file in errors.
// Exposed for tests and fuzzers.
void ParseCamerasBinary(std::string_view data, const std::string& source,
                        Reconstruction* reconstruction);
void ParseImagesBinary(std::string_view data, const std::string& source,
                       Reconstruction* reconstruction);
void ParsePoints3DBinary(std::string_view data, const std::string& source,
                         Reconstruction* reconstruction);
void ParseRigsBinary(std::string_view data, const std::string& source,
                     Reconstruction* reconstruction);
void ParseFramesBinary(std::string_view data, const std::string& source,
                       Reconstruction* reconstruction);
void ParseCamerasText(std::string_view data, const std::string& source,
                      Reconstruction* reconstruction);
void ParseImagesText(std::string_view data, const std::string& source,
                     Reconstruction* reconstruction);
void ParsePoints3DText(std::string_view data, const std::string& source,
                       Reconstruction* reconstruction);

}  // namespace linecloud
