#include "linecloud/io/colmap_model.h"

#include <cerrno>

#include <algorithm>
#include <fmt/format.h>
#include <ostream>

#include "linecloud/util/byte_reader.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"
#include "linecloud/util/text_parser.h"

namespace linecloud {
namespace {

constexpr size_t kPoseBytes = 7 * sizeof(double);

Rigid3d ReadPose(ByteReader& r, std::string_view what) {
  Rigid3d pose;
  const double qw = r.ReadFiniteDouble(what);
  const double qx = r.ReadFiniteDouble(what);
  const double qy = r.ReadFiniteDouble(what);
  const double qz = r.ReadFiniteDouble(what);
  pose.rotation = Eigen::Quaterniond(qw, qx, qy, qz);
  const double norm = pose.rotation.norm();
  if (!(norm > 1e-6)) {
    Fail("{}: '{}' has a zero quaternion at byte {}", r.Source(), what,
         r.Position() - 4 * sizeof(double));
  }
  if (std::abs(norm - 1.0) > 1e-12) pose.rotation.normalize();
  for (int i = 0; i < 3; ++i) pose.translation[i] = r.ReadFiniteDouble(what);
  return pose;
}

void WritePose(std::ostream& out, const Rigid3d& pose) {
  WriteLE(out, pose.rotation.w());
  WriteLE(out, pose.rotation.x());
  WriteLE(out, pose.rotation.y());
  WriteLE(out, pose.rotation.z());
  for (int i = 0; i < 3; ++i) WriteLE(out, pose.translation[i]);
}

SensorId ReadSensorId(ByteReader& r) {
  SensorId s;
  s.type = r.Read<int32_t>("sensor type");
  s.id = r.Read<uint32_t>("sensor id");
  return s;
}

void WriteSensorId(std::ostream& out, const SensorId& s) {
  WriteLE<int32_t>(out, s.type);
  WriteLE<uint32_t>(out, s.id);
}

void ExpectEnd(const ByteReader& r) {
  if (!r.AtEnd()) {
    Fail("{}: corrupt: {} unexpected trailing bytes", r.Source(), r.Remaining());
  }
}

template <typename Map>
std::vector<typename Map::key_type> SortedKeys(const Map& map) {
  std::vector<typename Map::key_type> keys;
  keys.reserve(map.size());
  for (const auto& [key, value] : map) keys.push_back(key);
  std::sort(keys.begin(), keys.end());
  return keys;
}

Eigen::Quaterniond ParseQuaternion(const std::vector<std::string_view>& tok, size_t i,
                                   const TextLines& lines) {
  Eigen::Quaterniond q(
      ParseNumber<double>(tok[i], lines, "QW"), ParseNumber<double>(tok[i + 1], lines, "QX"),
      ParseNumber<double>(tok[i + 2], lines, "QY"), ParseNumber<double>(tok[i + 3], lines, "QZ"));
  const double norm = q.norm();
  if (!(norm > 1e-6)) lines.FailHere("zero quaternion");
  // Normalise only when needed, so that bin <-> txt round trips are exact.
  if (std::abs(norm - 1.0) > 1e-12) q.normalize();
  return q;
}

}  // namespace

std::vector<Eigen::Vector3d> PointCoordinates(const Reconstruction& model,
                                              std::span<const uint64_t> ids) {
  std::vector<Eigen::Vector3d> xyz;
  xyz.reserve(ids.size());
  for (const uint64_t id : ids) xyz.push_back(model.points3D.at(id).xyz);
  return xyz;
}

std::vector<uint64_t> Reconstruction::SortedPoint3DIds() const { return SortedKeys(points3D); }

double Reconstruction::MeanTrackLength() const {
  if (points3D.empty()) return 0.0;
  size_t total = 0;
  for (const auto& [id, p] : points3D) total += p.track.size();
  return static_cast<double>(total) / static_cast<double>(points3D.size());
}

void Reconstruction::Check(std::string_view source) const {
  for (const auto& [id, camera] : cameras) camera.Check(source);
  for (const auto& [id, image] : images) {
    if (!cameras.count(image.camera_id)) {
      Fail("{}: image {} ('{}') refers to camera {} which is not in the model", source, id,
           image.name, image.camera_id);
    }
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      const Point2D& p = image.points2D[i];
      if (p.point3D_id != kInvalidPoint3DId && !points3D.count(p.point3D_id)) {
        Fail(
            "{}: image {} point2D {} refers to point3D {} which is not in "
            "the model",
            source, id, i, p.point3D_id);
      }
    }
  }
  for (const auto& [id, point] : points3D) {
    if (!point.xyz.allFinite()) {
      Fail("{}: point3D {} has non-finite coordinates", source, id);
    }
    for (const TrackElement& el : point.track) {
      const auto it = images.find(el.image_id);
      if (it == images.end()) {
        Fail(
            "{}: point3D {} track refers to image {} which is not in the "
            "model",
            source, id, el.image_id);
      }
      if (el.point2D_idx >= it->second.points2D.size()) {
        Fail(
            "{}: point3D {} track refers to point2D {} of image {} which "
            "has only {}",
            source, id, el.point2D_idx, el.image_id, it->second.points2D.size());
      }
    }
  }
}

// ---------------------------------------------------------------- binary ---

void ParseCamerasBinary(std::string_view data, const std::string& source, Reconstruction* rec) {
  ByteReader r(data, source);
  const uint64_t n = r.ReadCount("num_cameras", 4 + 4 + 8 + 8);
  for (uint64_t i = 0; i < n; ++i) {
    Camera camera;
    camera.camera_id = r.Read<uint32_t>("camera_id");
    const int model = r.Read<int32_t>("model_id");
    camera.model_id = CameraModelFromInt(model);
    if (camera.model_id == CameraModelId::kInvalid) {
      Fail("{}: camera {}: unsupported camera model id {}", source, camera.camera_id, model);
    }
    camera.width = r.Read<uint64_t>("width");
    camera.height = r.Read<uint64_t>("height");
    camera.params.resize(CameraModelNumParams(camera.model_id));
    for (double& p : camera.params) p = r.Read<double>("params");
    camera.Check(source);
    if (!rec->cameras.emplace(camera.camera_id, camera).second) {
      Fail("{}: duplicate camera id {}", source, camera.camera_id);
    }
  }
  ExpectEnd(r);
}

void ParseImagesBinary(std::string_view data, const std::string& source, Reconstruction* rec) {
  ByteReader r(data, source);
  const uint64_t n = r.ReadCount("num_images", 4 + kPoseBytes + 4 + 1 + 8);
  for (uint64_t i = 0; i < n; ++i) {
    Image image;
    image.image_id = r.Read<uint32_t>("image_id");
    image.cam_from_world = ReadPose(r, "cam_from_world");
    image.camera_id = r.Read<uint32_t>("camera_id");
    image.name = r.ReadCString("name");
    const uint64_t num_points2D = r.ReadCount("num_points2D", 24);
    image.points2D.resize(num_points2D);
    for (Point2D& p : image.points2D) {
      p.xy.x() = r.ReadFiniteDouble("points2D.x");
      p.xy.y() = r.ReadFiniteDouble("points2D.y");
      p.point3D_id = r.Read<uint64_t>("points2D.point3D_id");
    }
    const uint32_t id = image.image_id;
    if (!rec->images.emplace(id, std::move(image)).second) {
      Fail("{}: duplicate image id {}", source, id);
    }
  }
  ExpectEnd(r);
}

void ParsePoints3DBinary(std::string_view data, const std::string& source, Reconstruction* rec) {
  ByteReader r(data, source);
  const uint64_t n = r.ReadCount("num_points3D", 8 + 24 + 3 + 8 + 8);
  rec->points3D.reserve(rec->points3D.size() + n);
  for (uint64_t i = 0; i < n; ++i) {
    const uint64_t id = r.Read<uint64_t>("point3D_id");
    Point3D point;
    for (int k = 0; k < 3; ++k) {
      point.xyz[k] = r.Read<double>("xyz");
      if (!std::isfinite(point.xyz[k])) {
        Fail("{}: point3D {} has a non-finite coordinate", source, id);
      }
    }
    for (int k = 0; k < 3; ++k) point.color[k] = r.Read<uint8_t>("rgb");
    point.error = r.Read<double>("error");
    const uint64_t track_length = r.ReadCount("track_length", 8);
    point.track.resize(track_length);
    for (TrackElement& el : point.track) {
      el.image_id = r.Read<uint32_t>("track.image_id");
      el.point2D_idx = r.Read<uint32_t>("track.point2D_idx");
    }
    if (!rec->points3D.emplace(id, std::move(point)).second) {
      Fail("{}: duplicate point3D id {}", source, id);
    }
  }
  ExpectEnd(r);
}

void ParseRigsBinary(std::string_view data, const std::string& source, Reconstruction* rec) {
  ByteReader r(data, source);
  const uint64_t n = r.ReadCount("num_rigs", 8);
  for (uint64_t i = 0; i < n; ++i) {
    Rig rig;
    rig.rig_id = r.Read<uint32_t>("rig_id");
    const uint32_t num_sensors = r.Read<uint32_t>("num_sensors");
    if (num_sensors > r.Remaining() / 8 + 1) {
      Fail("{}: corrupt or truncated: rig {} claims {} sensors", source, rig.rig_id, num_sensors);
    }
    if (num_sensors > 0) rig.ref_sensor = ReadSensorId(r);
    for (uint32_t j = 1; j < num_sensors; ++j) {
      RigSensor sensor;
      sensor.sensor = ReadSensorId(r);
      if (r.Read<uint8_t>("has_pose")) {
        sensor.sensor_from_rig = ReadPose(r, "sensor_from_rig");
      }
      rig.sensors.push_back(sensor);
    }
    if (!rec->rigs.emplace(rig.rig_id, rig).second) {
      Fail("{}: duplicate rig id {}", source, rig.rig_id);
    }
  }
  ExpectEnd(r);
}

void ParseFramesBinary(std::string_view data, const std::string& source, Reconstruction* rec) {
  ByteReader r(data, source);
  const uint64_t n = r.ReadCount("num_frames", 4 + 4 + kPoseBytes + 4);
  for (uint64_t i = 0; i < n; ++i) {
    Frame frame;
    frame.frame_id = r.Read<uint32_t>("frame_id");
    frame.rig_id = r.Read<uint32_t>("rig_id");
    frame.rig_from_world = ReadPose(r, "rig_from_world");
    const uint32_t num_data = r.Read<uint32_t>("num_data_ids");
    if (num_data > r.Remaining() / 16) {
      Fail("{}: corrupt or truncated: frame {} claims {} data ids", source, frame.frame_id,
           num_data);
    }
    frame.data.resize(num_data);
    for (FrameData& d : frame.data) {
      d.sensor = ReadSensorId(r);
      d.data_id = r.Read<uint64_t>("data_id");
    }
    if (!rec->frames.emplace(frame.frame_id, frame).second) {
      Fail("{}: duplicate frame id {}", source, frame.frame_id);
    }
  }
  ExpectEnd(r);
}

namespace {

void WriteCamerasBinary(const Reconstruction& rec, std::ostream& out) {
  WriteLE<uint64_t>(out, rec.cameras.size());
  for (const auto& [id, camera] : rec.cameras) {
    WriteLE<uint32_t>(out, id);
    WriteLE<int32_t>(out, static_cast<int32_t>(camera.model_id));
    WriteLE<uint64_t>(out, camera.width);
    WriteLE<uint64_t>(out, camera.height);
    for (double p : camera.params) WriteLE(out, p);
  }
}

void WriteImagesBinary(const Reconstruction& rec, std::ostream& out) {
  WriteLE<uint64_t>(out, rec.images.size());
  for (const auto& [id, image] : rec.images) {
    WriteLE<uint32_t>(out, id);
    WritePose(out, image.cam_from_world);
    WriteLE<uint32_t>(out, image.camera_id);
    out.write(image.name.c_str(), image.name.size() + 1);
    WriteLE<uint64_t>(out, image.points2D.size());
    for (const Point2D& p : image.points2D) {
      WriteLE(out, p.xy.x());
      WriteLE(out, p.xy.y());
      WriteLE(out, p.point3D_id);
    }
  }
}

void WritePoints3DBinary(const Reconstruction& rec, std::ostream& out) {
  WriteLE<uint64_t>(out, rec.points3D.size());
  for (const uint64_t id : rec.SortedPoint3DIds()) {
    const Point3D& p = rec.points3D.at(id);
    WriteLE(out, id);
    for (int k = 0; k < 3; ++k) WriteLE(out, p.xyz[k]);
    for (int k = 0; k < 3; ++k) WriteLE(out, p.color[k]);
    WriteLE(out, p.error);
    WriteLE<uint64_t>(out, p.track.size());
    for (const TrackElement& el : p.track) {
      WriteLE(out, el.image_id);
      WriteLE(out, el.point2D_idx);
    }
  }
}

void WriteRigsBinary(const Reconstruction& rec, std::ostream& out) {
  WriteLE<uint64_t>(out, rec.rigs.size());
  for (const auto& [id, rig] : rec.rigs) {
    WriteLE<uint32_t>(out, id);
    const uint32_t num_sensors = rig.ref_sensor ? static_cast<uint32_t>(rig.sensors.size() + 1) : 0;
    WriteLE<uint32_t>(out, num_sensors);
    if (!rig.ref_sensor) continue;
    WriteSensorId(out, *rig.ref_sensor);
    for (const RigSensor& s : rig.sensors) {
      WriteSensorId(out, s.sensor);
      WriteLE<uint8_t>(out, s.sensor_from_rig ? 1 : 0);
      if (s.sensor_from_rig) WritePose(out, *s.sensor_from_rig);
    }
  }
}

void WriteFramesBinary(const Reconstruction& rec, std::ostream& out) {
  WriteLE<uint64_t>(out, rec.frames.size());
  for (const auto& [id, frame] : rec.frames) {
    WriteLE<uint32_t>(out, id);
    WriteLE<uint32_t>(out, frame.rig_id);
    WritePose(out, frame.rig_from_world);
    WriteLE<uint32_t>(out, static_cast<uint32_t>(frame.data.size()));
    for (const FrameData& d : frame.data) {
      WriteSensorId(out, d.sensor);
      WriteLE(out, d.data_id);
    }
  }
}

// ------------------------------------------------------------------ text ---

void WriteCamerasText(const Reconstruction& rec, std::ostream& out) {
  out << "# Camera list with one line of data per camera:\n"
         "#   CAMERA_ID, MODEL, WIDTH, HEIGHT, PARAMS[]\n"
      << "# Number of cameras: " << rec.cameras.size() << "\n";
  for (const auto& [id, c] : rec.cameras) {
    out << fmt::format("{} {} {} {}", id, CameraModelName(c.model_id), c.width, c.height);
    for (double p : c.params) out << fmt::format(" {}", p);
    out << "\n";
  }
}

void WriteImagesText(const Reconstruction& rec, std::ostream& out) {
  out << "# Image list with two lines of data per image:\n"
         "#   IMAGE_ID, QW, QX, QY, QZ, TX, TY, TZ, CAMERA_ID, NAME\n"
         "#   POINTS2D[] as (X, Y, POINT3D_ID)\n"
      << "# Number of images: " << rec.images.size() << "\n";
  for (const auto& [id, im] : rec.images) {
    const auto& q = im.cam_from_world.rotation;
    const auto& t = im.cam_from_world.translation;
    out << fmt::format("{} {} {} {} {} {} {} {} {} {}\n", id, q.w(), q.x(), q.y(), q.z(), t.x(),
                       t.y(), t.z(), im.camera_id, im.name);
    std::string line;
    for (const Point2D& p : im.points2D) {
      if (!line.empty()) line += ' ';
      const long long pid =
          p.point3D_id == kInvalidPoint3DId ? -1 : static_cast<long long>(p.point3D_id);
      line += fmt::format("{} {} {}", p.xy.x(), p.xy.y(), pid);
    }
    out << line << "\n";
  }
}

void WritePoints3DText(const Reconstruction& rec, std::ostream& out) {
  out << "# 3D point list with one line of data per point:\n"
         "#   POINT3D_ID, X, Y, Z, R, G, B, ERROR, TRACK[] as (IMAGE_ID, "
         "POINT2D_IDX)\n"
      << "# Number of points: " << rec.points3D.size()
      << fmt::format(", mean track length: {}\n", rec.MeanTrackLength());
  for (const uint64_t id : rec.SortedPoint3DIds()) {
    const Point3D& p = rec.points3D.at(id);
    out << fmt::format("{} {} {} {} {} {} {} {}", id, p.xyz.x(), p.xyz.y(), p.xyz.z(), p.color[0],
                       p.color[1], p.color[2], p.error);
    for (const TrackElement& el : p.track) {
      out << fmt::format(" {} {}", el.image_id, el.point2D_idx);
    }
    out << "\n";
  }
}

}  // namespace

void ParseCamerasText(std::string_view data, const std::string& source, Reconstruction* rec) {
  TextLines lines(data, source);
  std::string_view line;
  while (lines.Next(&line)) {
    const auto tok = SplitWhitespace(line);
    if (tok.size() < 4) lines.FailHere("expected CAMERA_ID MODEL WIDTH HEIGHT PARAMS[]");
    Camera camera;
    camera.camera_id = ParseNumber<uint32_t>(tok[0], lines, "CAMERA_ID");
    camera.model_id = CameraModelFromName(tok[1]);
    if (camera.model_id == CameraModelId::kInvalid) {
      lines.FailHere(
          fmt::format("camera {}: unsupported camera model '{}'", camera.camera_id, tok[1]));
    }
    camera.width = ParseNumber<uint64_t>(tok[2], lines, "WIDTH");
    camera.height = ParseNumber<uint64_t>(tok[3], lines, "HEIGHT");
    for (size_t i = 4; i < tok.size(); ++i) {
      camera.params.push_back(ParseNumber<double>(tok[i], lines, "PARAMS"));
    }
    camera.Check(fmt::format("{}:{}", source, lines.LineNumber()));
    if (!rec->cameras.emplace(camera.camera_id, camera).second) {
      lines.FailHere(fmt::format("duplicate camera id {}", camera.camera_id));
    }
  }
}

void ParseImagesText(std::string_view data, const std::string& source, Reconstruction* rec) {
  TextLines lines(data, source);
  std::string_view line;
  while (lines.Next(&line)) {
    const auto tok = SplitWhitespace(line);
    if (tok.size() < 10) {
      lines.FailHere("expected IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME");
    }
    Image image;
    image.image_id = ParseNumber<uint32_t>(tok[0], lines, "IMAGE_ID");
    image.cam_from_world.rotation = ParseQuaternion(tok, 1, lines);
    image.cam_from_world.translation = Eigen::Vector3d(ParseNumber<double>(tok[5], lines, "TX"),
                                                       ParseNumber<double>(tok[6], lines, "TY"),
                                                       ParseNumber<double>(tok[7], lines, "TZ"));
    image.camera_id = ParseNumber<uint32_t>(tok[8], lines, "CAMERA_ID");
    // Names may contain spaces: the rest of the line after CAMERA_ID.
    const size_t name_pos = tok[9].data() - line.data();
    image.name = std::string(line.substr(name_pos));
    while (!image.name.empty() && (image.name.back() == ' ' || image.name.back() == '\t')) {
      image.name.pop_back();
    }
    std::string_view points_line;
    if (!lines.NextRaw(&points_line)) {
      lines.FailHere(fmt::format("image {}: missing POINTS2D line (truncated?)", image.image_id));
    }
    const auto pts = SplitWhitespace(points_line);
    if (pts.size() % 3 != 0) {
      lines.FailHere(
          fmt::format("image {}: POINTS2D must be triples (X, Y, POINT3D_ID), got {} values",
                      image.image_id, pts.size()));
    }
    image.points2D.resize(pts.size() / 3);
    for (size_t i = 0; i < image.points2D.size(); ++i) {
      Point2D& p = image.points2D[i];
      p.xy.x() = ParseNumber<double>(pts[3 * i], lines, "POINTS2D.X");
      p.xy.y() = ParseNumber<double>(pts[3 * i + 1], lines, "POINTS2D.Y");
      const int64_t pid = ParseNumber<int64_t>(pts[3 * i + 2], lines, "POINTS2D.POINT3D_ID");
      p.point3D_id = pid < 0 ? kInvalidPoint3DId : static_cast<uint64_t>(pid);
    }
    const uint32_t id = image.image_id;
    if (!rec->images.emplace(id, std::move(image)).second) {
      lines.FailHere(fmt::format("duplicate image id {}", id));
    }
  }
}

void ParsePoints3DText(std::string_view data, const std::string& source, Reconstruction* rec) {
  TextLines lines(data, source);
  std::string_view line;
  while (lines.Next(&line)) {
    const auto tok = SplitWhitespace(line);
    if (tok.size() < 8 || (tok.size() - 8) % 2 != 0) {
      lines.FailHere(
          "expected POINT3D_ID X Y Z R G B ERROR followed by (IMAGE_ID, "
          "POINT2D_IDX) pairs");
    }
    const uint64_t id = ParseNumber<uint64_t>(tok[0], lines, "POINT3D_ID");
    Point3D p;
    p.xyz = Eigen::Vector3d(ParseNumber<double>(tok[1], lines, "X"),
                            ParseNumber<double>(tok[2], lines, "Y"),
                            ParseNumber<double>(tok[3], lines, "Z"));
    for (int k = 0; k < 3; ++k) {
      const unsigned c = ParseNumber<unsigned>(tok[4 + k], lines, "RGB");
      if (c > 255) lines.FailHere("colour component above 255");
      p.color[k] = static_cast<uint8_t>(c);
    }
    p.error = ParseNumber<double>(tok[7], lines, "ERROR");
    p.track.resize((tok.size() - 8) / 2);
    for (size_t i = 0; i < p.track.size(); ++i) {
      p.track[i].image_id = ParseNumber<uint32_t>(tok[8 + 2 * i], lines, "TRACK.IMAGE_ID");
      p.track[i].point2D_idx = ParseNumber<uint32_t>(tok[9 + 2 * i], lines, "TRACK.POINT2D_IDX");
    }
    if (!rec->points3D.emplace(id, std::move(p)).second) {
      lines.FailHere(fmt::format("duplicate point3D id {}", id));
    }
  }
}

Reconstruction ReadColmapModel(const std::string& dir) {
  if (!IsDirectory(dir)) {
    FailFile(FileExists(dir) ? ENOTDIR : ENOENT,
             "{}: not a directory (expected a COLMAP model folder)", dir);
  }
  Reconstruction rec;
  const auto path = [&](const char* name) { return JoinPaths(dir, name); };
  const bool binary = FileExists(path("cameras.bin")) || FileExists(path("images.bin")) ||
                      FileExists(path("points3D.bin"));
  const bool text = FileExists(path("cameras.txt")) || FileExists(path("images.txt")) ||
                    FileExists(path("points3D.txt"));
  if (!binary && !text) {
    Fail(
        "{}: no COLMAP model found (expected cameras, images, points3D as "
        ".bin or .txt)",
        dir);
  }
  if (binary) {
    if (FileExists(path("rigs.bin"))) {
      ParseRigsBinary(ReadFileToString(path("rigs.bin")), path("rigs.bin"), &rec);
    }
    ParseCamerasBinary(ReadFileToString(path("cameras.bin")), path("cameras.bin"), &rec);
    if (FileExists(path("frames.bin"))) {
      ParseFramesBinary(ReadFileToString(path("frames.bin")), path("frames.bin"), &rec);
    }
    ParseImagesBinary(ReadFileToString(path("images.bin")), path("images.bin"), &rec);
    ParsePoints3DBinary(ReadFileToString(path("points3D.bin")), path("points3D.bin"), &rec);
  } else {
    ParseCamerasText(ReadFileToString(path("cameras.txt")), path("cameras.txt"), &rec);
    ParseImagesText(ReadFileToString(path("images.txt")), path("images.txt"), &rec);
    ParsePoints3DText(ReadFileToString(path("points3D.txt")), path("points3D.txt"), &rec);
  }
  rec.Check(dir);
  return rec;
}

void WriteColmapModel(const Reconstruction& rec, const std::string& dir, ModelFormat format) {
  CreateDirectories(dir);
  if (format == ModelFormat::kBinary) {
    WriteFileAtomically(JoinPaths(dir, "cameras.bin"),
                        [&](std::ostream& o) { WriteCamerasBinary(rec, o); });
    WriteFileAtomically(JoinPaths(dir, "images.bin"),
                        [&](std::ostream& o) { WriteImagesBinary(rec, o); });
    WriteFileAtomically(JoinPaths(dir, "points3D.bin"),
                        [&](std::ostream& o) { WritePoints3DBinary(rec, o); });
    if (!rec.rigs.empty()) {
      WriteFileAtomically(JoinPaths(dir, "rigs.bin"),
                          [&](std::ostream& o) { WriteRigsBinary(rec, o); });
    }
    if (!rec.frames.empty()) {
      WriteFileAtomically(JoinPaths(dir, "frames.bin"),
                          [&](std::ostream& o) { WriteFramesBinary(rec, o); });
    }
  } else {
    WriteFileAtomically(JoinPaths(dir, "cameras.txt"),
                        [&](std::ostream& o) { WriteCamerasText(rec, o); });
    WriteFileAtomically(JoinPaths(dir, "images.txt"),
                        [&](std::ostream& o) { WriteImagesText(rec, o); });
    WriteFileAtomically(JoinPaths(dir, "points3D.txt"),
                        [&](std::ostream& o) { WritePoints3DText(rec, o); });
  }
}

}  // namespace linecloud
