#include "linecloud/colmap/dataset.h"

#include <algorithm>
#include <filesystem>
#include <set>

#include "linecloud/io/colmap_model.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/text_parser.h"

namespace linecloud {
namespace fs = std::filesystem;

namespace {

bool IsImageFile(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return std::tolower(c); });
  return ext == ".jpg" || ext == ".jpeg" || ext == ".png" || ext == ".tif" || ext == ".tiff" ||
         ext == ".bmp" || ext == ".pgm" || ext == ".ppm";
}

// The 16 numbers of "T_BS: ... data: [ ... ]" in an EuRoC sensor yaml.
Rigid3d ReadBodyFromSensor(const std::string& path) {
  const std::string text = ReadFileToString(path);
  const size_t key = text.find("T_BS:");
  if (key == std::string::npos) Fail("{}: no T_BS entry", path);
  const size_t open = text.find('[', text.find("data:", key));
  const size_t close = text.find(']', open);
  if (open == std::string::npos || close == std::string::npos)
    Fail("{}: T_BS has no data: [...]", path);
  std::string numbers = text.substr(open + 1, close - open - 1);
  std::replace(numbers.begin(), numbers.end(), ',', ' ');
  std::replace(numbers.begin(), numbers.end(), '\n', ' ');
  std::vector<double> v;
  for (std::string_view token : SplitWhitespace(numbers)) {
    double x = 0;
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), x);
    if (ec != std::errc() || end != token.data() + token.size() || !std::isfinite(x)) {
      Fail("{}: T_BS: '{}' is not a number", path, token);
    }
    v.push_back(x);
  }
  if (v.size() != 16) Fail("{}: T_BS has {} numbers, expected 16", path, v.size());
  Eigen::Matrix3d R;
  R << v[0], v[1], v[2], v[4], v[5], v[6], v[8], v[9], v[10];
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-4 || R.determinant() < 0) {
    Fail("{}: T_BS is not a rigid transform", path);
  }
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(R, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d R_clean = svd.matrixU() * svd.matrixV().transpose();
  return Rigid3d(Eigen::Quaterniond(R_clean).normalized(), Eigen::Vector3d(v[3], v[7], v[11]));
}

void ReadImu(const std::string& path, DatasetSensors* sensors) {
  const std::string text = ReadFileToString(path);
  TextLines lines(text, path);
  std::string_view line;
  while (lines.Next(&line)) {
    std::string row(line);
    std::replace(row.begin(), row.end(), ',', ' ');
    const auto tokens = SplitWhitespace(row);
    if (tokens.size() != 7)
      lines.FailHere(fmt::format("expected 7 columns, found {}", tokens.size()));
    sensors->imu_time_ns.push_back(ParseNumber<int64_t>(tokens[0], lines, "timestamp"));
    Eigen::Vector3d a;
    for (int k = 0; k < 3; ++k) a[k] = ParseNumber<double>(tokens[4 + k], lines, "a_RS_S");
    sensors->imu_accel.push_back(a);
  }
  if (sensors->imu_time_ns.empty()) Fail("{}: no IMU samples", path);
}

}  // namespace

bool EvalDataset::IsQueryImage(const std::string& image_name) const {
  for (const auto& group : query_groups) {
    if (std::find(group.begin(), group.end(), image_name) != group.end()) return true;
  }
  return false;
}

std::vector<std::string> EvalDataset::MapOnlyImages() const {
  std::vector<std::string> out;
  for (const std::string& name : images) {
    if (!IsQueryImage(name)) out.push_back(name);
  }
  return out;
}

std::optional<int64_t> EurocTimestampNs(const std::string& image_name) {
  const size_t underscore = image_name.find("_c");
  if (underscore == std::string::npos || underscore == 0) return std::nullopt;
  int64_t t = 0;
  const auto [end, ec] = std::from_chars(image_name.data(), image_name.data() + underscore, t);
  if (ec != std::errc() || end != image_name.data() + underscore) return std::nullopt;
  return t;
}

Eigen::Vector3d GravityInBody(const DatasetSensors& sensors, int64_t time_ns, int64_t window_ns) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  int n = 0;
  for (size_t i = 0; i < sensors.imu_time_ns.size(); ++i) {
    if (std::llabs(sensors.imu_time_ns[i] - time_ns) <= window_ns) {
      sum += sensors.imu_accel[i];
      ++n;
    }
  }
  if (n == 0 || sum.norm() == 0)
    Fail("no IMU sample within {} ms of t = {} ns", window_ns / 1e6, time_ns);
  // An accelerometer at rest measures the reaction to gravity (pointing up).
  return -sum.normalized();
}

EvalDataset ReadEvalDataset(const std::string& dir) {
  EvalDataset d;
  d.dir = dir;
  fs::path p = fs::path(dir).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  d.name = p.filename().string();
  if (!IsDirectory(dir)) Fail("{}: dataset directory not found", dir);
  const std::string images_dir = JoinPaths(dir, "images");
  if (!IsDirectory(images_dir)) Fail("{}: no images/ directory", dir);
  for (const auto& entry : fs::directory_iterator(images_dir)) {
    if (entry.is_regular_file() && IsImageFile(entry.path())) {
      d.images.push_back(entry.path().filename().string());
    }
  }
  std::sort(d.images.begin(), d.images.end());
  if (d.images.empty()) Fail("{}: no images", images_dir);
  const std::set<std::string> image_set(d.images.begin(), d.images.end());

  const std::string cameras_path = JoinPaths(dir, "cameras.txt");
  Reconstruction cams;
  ParseCamerasText(ReadFileToString(cameras_path), cameras_path, &cams);
  if (cams.cameras.empty()) Fail("{}: no cameras", cameras_path);
  d.cameras = cams.cameras;

  const std::string image_cameras_path = JoinPaths(dir, "image_cameras.txt");
  if (FileExists(image_cameras_path)) {
    const std::string text = ReadFileToString(image_cameras_path);
    TextLines lines(text, image_cameras_path);
    std::string_view line;
    while (lines.Next(&line)) {
      const auto tokens = SplitWhitespace(line);
      if (tokens.size() != 2) lines.FailHere("expected NAME CAMERA_ID");
      const std::string name(tokens[0]);
      const auto id = ParseNumber<uint32_t>(tokens[1], lines, "CAMERA_ID");
      if (!image_set.count(name)) lines.FailHere(fmt::format("image '{}' is not in images/", name));
      if (!d.cameras.count(id)) lines.FailHere(fmt::format("camera {} is not in cameras.txt", id));
      d.image_camera[name] = id;
    }
  } else if (d.cameras.size() != 1) {
    Fail("{}: {} cameras but no image_cameras.txt to assign them", cameras_path, d.cameras.size());
  }
  for (const std::string& name : d.images) {
    if (!d.image_camera.count(name)) {
      if (d.cameras.size() != 1) Fail("{}: image '{}' has no camera", image_cameras_path, name);
      d.image_camera[name] = d.cameras.begin()->first;
    }
  }

  const std::string queries_path = JoinPaths(dir, "queries.txt");
  {
    const std::string text = ReadFileToString(queries_path);
    TextLines lines(text, queries_path);
    std::string_view line;
    std::set<std::string> seen;
    while (lines.Next(&line)) {
      std::vector<std::string> group;
      for (std::string_view token : SplitWhitespace(line)) {
        const std::string name(token);
        if (!image_set.count(name))
          lines.FailHere(fmt::format("image '{}' is not in images/", name));
        if (!seen.insert(name).second)
          lines.FailHere(fmt::format("image '{}' is in two query groups", name));
        group.push_back(name);
      }
      d.query_groups.push_back(std::move(group));
    }
    if (d.query_groups.empty()) Fail("{}: no query groups", queries_path);
    for (size_t g = 0; g < d.query_groups.size(); ++g) {
      if (d.images.size() - d.query_groups[g].size() < 2) {
        Fail("{}: group {} leaves fewer than 2 images for its map", queries_path, g + 1);
      }
    }
  }

  const std::string gt_path = JoinPaths(dir, "gt/images.txt");
  if (FileExists(gt_path)) {
    Reconstruction gt;
    ParseImagesText(ReadFileToString(gt_path), gt_path, &gt);
    for (const auto& [id, image] : gt.images) {
      if (!image_set.count(image.name))
        Fail("{}: image '{}' is not in images/", gt_path, image.name);
      d.ground_truth[image.name] = image.cam_from_world;
    }
  }

  const std::string meta = JoinPaths(dir, "meta");
  if (IsDirectory(meta) && FileExists(JoinPaths(meta, "imu0_window.csv"))) {
    DatasetSensors sensors;
    // camK_sensor.yaml belongs to the camera of the images named *_cK.
    for (int k = 0; k < 8; ++k) {
      const std::string yaml = JoinPaths(meta, fmt::format("cam{}_sensor.yaml", k));
      if (!FileExists(yaml)) continue;
      const std::string suffix = fmt::format("_c{}.", k);
      std::optional<uint32_t> camera_id;
      for (const auto& [name, id] : d.image_camera) {
        if (name.find(suffix) != std::string::npos) camera_id = id;
      }
      if (!camera_id) Fail("{}: no image named *{}* for this sensor", yaml, suffix);
      sensors.body_from_cam[*camera_id] = ReadBodyFromSensor(yaml);
    }
    ReadImu(JoinPaths(meta, "imu0_window.csv"), &sensors);
    d.sensors = std::move(sensors);
  }
  return d;
}

}  // namespace linecloud
