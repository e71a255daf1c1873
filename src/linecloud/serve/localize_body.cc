#include "linecloud/serve/localize_body.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>

#include "linecloud/io/json_util.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/localize.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/pipeline/localizer_option_table.h"
#include "linecloud/serve/wire.h"
#include "linecloud/util/base64.h"

namespace linecloud {
namespace {

using json = nlohmann::json;

// The fields of a request that are not options: the photo or frames and
// what the device knows of them.
constexpr std::string_view kRigFields[] = {"method", "gravity", "points_local", "scale_known"};

bool IsRigField(std::string_view name) {
  return std::find(std::begin(kRigFields), std::end(kRigFields), name) != std::end(kRigFields);
}

[[noreturn]] void TooManyFrames(size_t n, int max_frames) {
  throw FramesOverLimit(
      fmt::format("{} frames: this server takes at most {} in one request (serve --max-frames)", n,
                  max_frames));
}

Eigen::Vector3d GravityFromJson(const json& g) {
  if (g.is_string()) return ParseDirection(g.get<std::string>(), "gravity");
  if (g.is_array() && g.size() == 3 && g[0].is_number() && g[1].is_number() && g[2].is_number()) {
    const Eigen::Vector3d v(g[0].get<double>(), g[1].get<double>(), g[2].get<double>());
    // Scaled first: a direction of huge (or tiny) numbers has no finite norm.
    if (v.allFinite() && v.cwiseAbs().maxCoeff() > 0) return v / v.cwiseAbs().maxCoeff();
  }
  Fail("gravity: expected a finite non-zero direction [x, y, z] or \"x,y,z\"");
}

bool ScaleKnownFromText(const std::string& text) {
  if (text == "true") return true;
  if (text == "false") return false;
  Fail("scale_known: expected true or false, got {}", ShownInMessage(json(text)));
}

// "image[12]" -> 12 for prefix "image"; nullopt when the name is not PREFIX[DIGITS].
std::optional<size_t> IndexedPart(const std::string& name, std::string_view prefix) {
  if (name.size() < prefix.size() + 3 || name.compare(0, prefix.size(), prefix) != 0 ||
      name[prefix.size()] != '[' || name.back() != ']') {
    return std::nullopt;
  }
  const std::string digits = name.substr(prefix.size() + 1, name.size() - prefix.size() - 2);
  if (digits.empty() || digits.size() > 4 ||
      !std::all_of(digits.begin(), digits.end(), [](unsigned char c) { return std::isdigit(c); }) ||
      (digits.size() > 1 && digits[0] == '0')) {
    Fail("multipart: part {}: expected {}[0], {}[1], ...", ShownInMessage(json(name)), prefix,
         prefix);
  }
  return std::stoul(digits);
}

// Keypoints that are not a photo's: most of them at one pixel (10 082 copies
// of one keypoint held a worker until the deadline: every sample degenerate).
// A real extractor repeats a location for its orientations (COLMAP's SIFT:
// ~1.2 keypoints a location), never for most keypoints.
void CheckKeypointsSpread(const std::vector<SiftKeypoint>& keypoints, const std::string& where) {
  if (keypoints.size() < 20) return;
  // A pixel's column or row (clamped first: a float of 1e30 is no int64).
  const auto cell = [](float v) {
    const double clamped = std::isfinite(v) ? std::clamp<double>(v, -1e9, 1e9) : 1e9;
    return static_cast<uint64_t>(static_cast<int64_t>(std::floor(clamped)) & 0xffffffff);
  };
  std::unordered_map<uint64_t, size_t> at;  // keypoints per pixel
  size_t most = 0;
  for (const SiftKeypoint& k : keypoints) most = std::max(most, ++at[cell(k.x) << 32 | cell(k.y)]);
  if (2 * at.size() < keypoints.size() || most > std::max<size_t>(16, keypoints.size() / 10)) {
    Fail("{}: {} keypoints at {} pixels ({} at one): not the features of a photo", where,
         keypoints.size(), at.size(), most);
  }
}

// One frame's client features from its JSON object (`where` names it).
void ReadFeatures(const json& j, const std::string& where, WireFrame* frame) {
  if (!j.is_object()) Fail("{}: expected an object", where);
  for (const char* key : {"camera", "keypoints", "descriptors"}) {
    if (!j.contains(key)) Fail("{}: field '{}' is missing", where, key);
  }
  const std::string prefix = where == "body" ? "" : where + ".";
  frame->camera = CameraFromJson(j["camera"], prefix + "camera");
  CheckServedCamera(frame->camera, prefix + "camera");
  const json& keypoints = j["keypoints"];
  if (!keypoints.is_array()) Fail("{}keypoints: expected [[x, y], ...]", prefix);
  frame->features.keypoints.reserve(keypoints.size());
  for (size_t i = 0; i < keypoints.size(); ++i) {
    const json& k = keypoints[i];
    if (!k.is_array() || k.size() != 2 || !k[0].is_number() || !k[1].is_number()) {
      Fail("{}keypoints[{}]: expected [x, y]", prefix, i);
    }
    frame->features.keypoints.push_back({k[0].get<float>(), k[1].get<float>(), 0, 0});
  }
  CheckKeypointsSpread(frame->features.keypoints, prefix + "keypoints");
  if (!j["descriptors"].is_string()) {
    Fail("{}descriptors: expected base64 of N x 128 bytes", prefix);
  }
  const std::string d = Base64Decode(j["descriptors"].get<std::string>(), prefix + "descriptors");
  frame->features.descriptors.assign(d.begin(), d.end());
  frame->name = where == "body" ? "features" : where;
}

// The fields every body may have besides its photos: method, gravity, local points, their scale.
void ReadRigFields(const json& j, LocalizeBody* body) {
  if (j.contains("method")) {
    if (!j["method"].is_string()) Fail("method: expected a name");
    body->method = j["method"].get<std::string>();
  }
  if (j.contains("gravity") && !j["gravity"].is_null())
    body->gravity = GravityFromJson(j["gravity"]);
  if (j.contains("points_local")) {
    body->points_local = ParseLocalPointsJson(j["points_local"], "points_local");
  }
  if (j.contains("scale_known") && !j["scale_known"].is_null()) {
    if (!j["scale_known"].is_boolean()) Fail("scale_known: expected true or false");
    body->scale_known = j["scale_known"].get<bool>();
  }
}

}  // namespace

// A request's camera within what any real camera is (Camera::Check has made
// sure it is well-formed): at most 1 000 000 pixels a side (2^63 was taken),
// focal lengths 0.01-1000 times the larger side (a 0.06-176 degree field of
// view; focal 1e308 kept RANSAC busy until the deadline).
void CheckServedCamera(const Camera& camera, const std::string& where) {
  constexpr uint64_t kMaxSide = 1'000'000;
  if (camera.width > kMaxSide || camera.height > kMaxSide) {
    Fail("{}: {}x{} pixels: at most {} a side", where, camera.width, camera.height, kMaxSide);
  }
  const double side = static_cast<double>(std::max(camera.width, camera.height));
  for (const double f : {camera.FocalLengthX(), camera.FocalLengthY()}) {
    if (!(f >= 0.01 * side && f <= 1000 * side)) {
      Fail("{}: focal length {} is not 0.01-1000 times the image's larger side ({} px)", where, f,
           side);
    }
  }
  // Inside the image (a principal point of 1e12 kept RANSAC busy until the deadline).
  const Eigen::Vector2d c = camera.PrincipalPoint();
  if (!(c.x() >= 0 && c.x() <= camera.width && c.y() >= 0 && c.y() <= camera.height)) {
    const std::string hint = CameraMistakeHint(camera);
    Fail("{}: principal point ({}, {}) is outside the {}x{} image{}{}", where, c.x(), c.y(),
         camera.width, camera.height, hint.empty() ? "" : "; ", hint);
  }
}

std::vector<QueryPhoto> LocalizeBody::Photos() const {
  std::vector<QueryPhoto> photos(frames.size());
  for (size_t k = 0; k < frames.size(); ++k) {
    const WireFrame& f = frames[k];
    QueryPhoto& p = photos[k];
    if (f.image.empty()) {
      p.features = &f.features;
    } else {
      p.encoded = {reinterpret_cast<const uint8_t*>(f.image.data()), f.image.size()};
    }
    p.camera = f.camera;
    p.cam_from_rig = f.cam_from_rig;
    p.name = f.name;
  }
  return photos;
}

void LocalizeBody::SetOn(LocalizeRequest* request) const {
  request->method = method;
  request->gravity = gravity;
  request->points_local = points_local;
  request->scale_known = scale_known;
}

LocalizeBody ReadMultipartBody(const std::map<std::string, std::string>& parts, int max_frames) {
  LocalizeBody body;
  // The frames: image[k] with camera[k] (or one camera) and cam_from_rig[k], or one image.
  std::map<size_t, const std::string*> images, cameras, poses;
  for (const auto& [name, value] : parts) {
    if (auto k = IndexedPart(name, "image")) {
      images[*k] = &value;
    } else if (auto c = IndexedPart(name, "camera")) {
      cameras[*c] = &value;
    } else if (auto p = IndexedPart(name, "cam_from_rig")) {
      poses[*p] = &value;
    }
    if (images.size() > static_cast<size_t>(max_frames)) TooManyFrames(images.size(), max_frames);
  }
  const auto part = [&](const std::string& name) {
    const auto it = parts.find(name);
    return it == parts.end() ? nullptr : &it->second;
  };
  const bool rig = !images.empty();
  if (rig && part("image")) Fail("multipart: give 'image' (one photo) or image[0], image[1], ...");
  if (!rig && !part("image")) Fail("multipart: the 'image' part is missing");
  const size_t n = rig ? images.size() : 1;
  if (rig && images.rbegin()->first != n - 1) {
    size_t missing = 0;
    while (images.count(missing)) ++missing;
    Fail("multipart: image[{}] without image[{}] (frames are image[0], image[1], ... in order)",
         images.rbegin()->first, missing);
  }
  for (const auto& [label, indexed] : {std::pair{"camera", &cameras}, {"cam_from_rig", &poses}}) {
    for (const auto& [k, value] : *indexed) {
      if (k >= n) Fail("multipart: {}[{}] has no image[{}]", label, k, k);
    }
  }
  if (!cameras.empty() && part("camera")) {
    Fail("multipart: give one 'camera' for every frame or camera[k] for each, not both");
  }
  if (!rig && !cameras.empty()) Fail("multipart: camera[k] goes with image[k]");
  if (!rig && !poses.empty()) Fail("multipart: cam_from_rig[k] goes with image[k]");
  body.frames.resize(n);
  for (size_t k = 0; k < n; ++k) {
    WireFrame& f = body.frames[k];
    f.name = rig ? fmt::format("image[{}]", k) : "image";
    f.image = rig ? *images.at(k) : *part("image");
    if (f.image.empty()) Fail("{}: an empty part, not a photo", f.name);
    const std::string camera_part = cameras.empty() ? "camera" : fmt::format("camera[{}]", k);
    const std::string* camera =
        cameras.empty() ? part("camera") : (cameras.count(k) ? cameras.at(k) : nullptr);
    if (!camera) Fail("multipart: the '{}' part is missing", camera_part);
    f.camera = ParseCameraString(*camera, camera_part + " part");
    CheckServedCamera(f.camera, camera_part);
    if (poses.count(k)) {
      f.cam_from_rig = JsonPose(ParseRequestJson(*poses.at(k), fmt::format("cam_from_rig[{}]", k)),
                                fmt::format("cam_from_rig[{}]", k));
    } else if (n > 1) {
      Fail(
          "multipart: the 'cam_from_rig[{}]' part is missing ({{\"q\": [w, x, y, z], \"t\": "
          "[x, y, z]}}: frame {} in the rig)",
          k, k);
    }
  }
  if (const std::string* m = part("method")) body.method = *m;
  if (const std::string* g = part("gravity")) body.gravity = ParseDirection(*g, "gravity");
  if (const std::string* p = part("points_local")) {
    body.points_local = ParseLocalPointsJson(ParseRequestJson(*p, "points_local"), "points_local");
  }
  if (const std::string* s = part("scale_known")) body.scale_known = ScaleKnownFromText(*s);
  // The other parts: request options, as text (a part that is none is named by the server).
  for (const auto& [name, value] : parts) {
    if (name == "image" || name == "camera" || IsRigField(name) || IndexedPart(name, "image") ||
        IndexedPart(name, "camera") || IndexedPart(name, "cam_from_rig")) {
      continue;
    }
    const OptionSpec* spec = FindLocalizerOption(name);
    body.options[name] = spec && spec->scope == OptionScope::kRequest
                             ? ParseOptionText(*spec, value, "multipart")
                             : json(value);
  }
  return body;
}

LocalizeBody ReadJsonBody(const json& j, int max_frames) {
  if (!j.is_object()) Fail("body: expected a JSON object");
  LocalizeBody body;
  if (j.contains("frames")) {
    for (const char* key : {"camera", "keypoints", "descriptors"}) {
      if (j.contains(key)) Fail("body: '{}' goes in each of 'frames', not beside them", key);
    }
    const json& frames = j["frames"];
    if (!frames.is_array() || frames.empty()) {
      Fail("frames: expected [{{camera, keypoints, descriptors, cam_from_rig}}, ...]");
    }
    if (frames.size() > static_cast<size_t>(max_frames)) TooManyFrames(frames.size(), max_frames);
    body.frames.resize(frames.size());
    for (size_t k = 0; k < frames.size(); ++k) {
      const std::string where = fmt::format("frames[{}]", k);
      ReadFeatures(frames[k], where, &body.frames[k]);
      RefuseUnknownFields(frames[k], {"camera", "keypoints", "descriptors", "cam_from_rig"}, where);
      if (frames[k].contains("cam_from_rig")) {
        body.frames[k].cam_from_rig = JsonPose(frames[k]["cam_from_rig"], where + ".cam_from_rig");
      } else if (frames.size() > 1) {
        Fail("{}: field 'cam_from_rig' is missing (the frame's pose in the rig)", where);
      }
    }
  } else {
    body.frames.resize(1);
    ReadFeatures(j, "body", &body.frames[0]);
  }
  ReadRigFields(j, &body);
  for (const auto& [key, value] : j.items()) {
    if (key != "frames" && key != "camera" && key != "keypoints" && key != "descriptors" &&
        !IsRigField(key)) {
      body.options[key] = value;
    }
  }
  return body;
}

}  // namespace linecloud
