// The evaluation dataset layout of docs/data.md: images/,
// cameras.txt (known, fixed intrinsics), optional image_cameras.txt,
// queries.txt (query groups), optional gt/images.txt (independent ground
// truth, cam_from_world) and optional meta/ (EuRoC sensor files: a
// calibrated camera rig and an IMU).
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// EuRoC-style sensors: body_from_sensor (T_BS) per camera and accelerometer
// samples (body = IMU frame).
struct DatasetSensors {
  std::map<uint32_t, Rigid3d> body_from_cam;  // by camera id
  std::vector<int64_t> imu_time_ns;
  std::vector<Eigen::Vector3d> imu_accel;  // m/s², body frame
};

struct EvalDataset {
  std::string dir;
  std::string name;                              // last path component(s)
  std::map<uint32_t, Camera> cameras;            // cameras.txt
  std::vector<std::string> images;               // sorted names in images/
  std::map<std::string, uint32_t> image_camera;  // name -> camera id
  std::vector<std::vector<std::string>> query_groups;
  std::map<std::string, Rigid3d> ground_truth;  // gt/images.txt, cam_from_world (metres)
  std::optional<DatasetSensors> sensors;        // meta/*_sensor.yaml + imu0_window.csv

  bool IsQueryImage(const std::string& image_name) const;
  // Images in no query group: the cameras every map keeps.
  std::vector<std::string> MapOnlyImages() const;
};

// Reads and checks the layout; throws Error naming the file and line for
// missing or malformed files, unknown images or cameras in the lists, and
// images that appear in two query groups.
EvalDataset ReadEvalDataset(const std::string& dir);

// EuRoC image names "<timestamp ns>_c<k>.<ext>": the timestamp; nullopt for other names.
std::optional<int64_t> EurocTimestampNs(const std::string& image_name);

// Mean accelerometer reading within ±window_ns of `time_ns`, as a unit vector
// pointing down (gravity, i.e. minus the specific force of a sensor at rest), body frame.
// Throws Error when no sample lies in the window.
Eigen::Vector3d GravityInBody(const DatasetSensors& sensors, int64_t time_ns,
                              int64_t window_ns = 25'000'000);

}  // namespace linecloud
