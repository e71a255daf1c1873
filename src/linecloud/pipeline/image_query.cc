#include "linecloud/pipeline/image_query.h"

#include <charconv>
#include <chrono>
#include <cmath>
#include <unordered_map>

#include <fmt/format.h>

#include "linecloud/io/colmap_database.h"
#include "linecloud/io/track_descriptors.h"
#include "linecloud/localize/query_json.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"
#include "linecloud/util/text_parser.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

MapDescriptors MapDescriptorsFromCloud(const LineCloud& cloud, const std::string& source) {
  if (!cloud.has_descriptors()) {
    Fail(
        "{}: the map has no descriptors to match a photo to; lift it with the model's COLMAP "
        "database",
        source);
  }
  if (cloud.descriptor_dim != 128 || cloud.descriptor_type != "colmap-sift-uint8") {
    Fail("{}: descriptors are {}-D '{}', but photos give 128-D colmap-sift-uint8", source,
         cloud.descriptor_dim, cloud.descriptor_type);
  }
  return {cloud.ids, cloud.descriptors};
}

MapDescriptors MapDescriptorsFromModel(const Reconstruction& model, const std::string& database) {
  const ColmapDatabase db(database);
  MapDescriptors out;
  out.ids = model.SortedPoint3DIds();
  const PointDescriptors d =
      ComputePointDescriptors(model, out.ids, db, DescriptorAggregation::kMedoid);
  if (d.dim != 128) Fail("{}: descriptors are {}-D, expected 128-D SIFT", database, d.dim);
  out.descriptors = d.data;
  return out;
}

Camera ParseCameraString(const std::string& text, const std::string& what) {
  const auto tokens = SplitWhitespace(text);
  if (tokens.size() < 3) {
    Fail("{} '{}': expected \"MODEL WIDTH HEIGHT PARAMS...\" (COLMAP's cameras.txt order)", what,
         text);
  }
  Camera camera;
  camera.model_id = CameraModelFromName(tokens[0]);
  if (camera.model_id == CameraModelId::kInvalid &&
      CameraModelFromName(tokens[1]) != CameraModelId::kInvalid) {
    Fail(
        "{}: unknown camera model '{}': this looks like a line of COLMAP's cameras.txt, which "
        "starts with the camera's id; drop the id ('{} ...')",
        what, tokens[0], tokens[1]);
  }
  if (camera.model_id == CameraModelId::kInvalid) {
    Fail(
        "{}: unknown camera model '{}' (SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, "
        "OPENCV, OPENCV_FISHEYE, FULL_OPENCV)",
        what, tokens[0]);
  }
  const auto number = [&](size_t i) {
    double v = 0;
    const std::string_view t = tokens[i];
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
    if (ec != std::errc() || ptr != t.data() + t.size() || !std::isfinite(v)) {
      Fail("{}: '{}' is not a finite number", what, t);
    }
    return v;
  };
  const double w = number(1), h = number(2);
  if (!(w >= 1 && h >= 1 && w <= 1e6 && h <= 1e6) || w != std::floor(w) || h != std::floor(h)) {
    Fail("{}: width and height must be whole numbers of pixels, got {} x {}", what, tokens[1],
         tokens[2]);
  }
  camera.width = static_cast<uint64_t>(w);
  camera.height = static_cast<uint64_t>(h);
  for (size_t i = 3; i < tokens.size(); ++i) camera.params.push_back(number(i));
  const int expected = CameraModelNumParams(camera.model_id);
  if (static_cast<int>(camera.params.size()) != expected) {
    Fail("{}: {} takes {} parameters, got {}", what, tokens[0], expected, camera.params.size());
  }
  camera.Check(what);
  return camera;
}

Eigen::Vector3d ParseDirection(const std::string& text, const std::string& option) {
  Eigen::Vector3d v;
  size_t start = 0;
  for (int k = 0; k < 3; ++k) {
    const size_t end = k < 2 ? text.find(',', start) : text.size();
    if (end == std::string::npos) Fail("{} '{}': expected x,y,z", option, text);
    const std::string_view t(text.data() + start, end - start);
    const auto [ptr, ec] = std::from_chars(t.data(), t.data() + t.size(), v[k]);
    if (ec != std::errc() || ptr != t.data() + t.size() || !std::isfinite(v[k])) {
      Fail("{} '{}': expected x,y,z with three finite numbers", option, text);
    }
    start = end + 1;
  }
  // Scaled first: a direction of huge (or tiny) numbers has no finite norm.
  const double scale = v.cwiseAbs().maxCoeff();
  if (!(scale > 0)) Fail("{} '{}': a direction cannot be zero", option, text);
  return (v / scale).normalized();
}

ImageLimits PhotoLimits(const Camera& camera, const ImageQueryOptions& options) {
  return {.max_pixels = options.max_pixels,
          .expected_width = camera.width,
          .expected_height = camera.height};
}

void ExtractImageFeatures(const GreyImage& image, const std::string& name,
                          const ImageQueryOptions& options, ImageQuery* q) {
  if (options.progress) {
    options.progress(
        fmt::format("extracting SIFT from {} ({}x{})", name, image.width, image.height));
  }
  const auto start = Clock::now();
  SiftOptions sift = options.sift;
  sift.threads = options.threads;  // the colmap extractor's; OpenCV's pool is process-wide
  q->features = ExtractSift(image, sift);
  q->times.extract_ms = MsSince(start);
}

ImageQuery ExtractImageQuery(const std::string& image_path, const Camera& camera,
                             const ImageQueryOptions& options) {
  ImageQuery out;
  const auto start = Clock::now();
  // The header is checked against the camera and the pixel cap before decoding.
  out.image = ReadGreyImage(image_path, PhotoLimits(camera, options));
  out.times.decode_ms = MsSince(start);
  ExtractImageFeatures(out.image, image_path, options, &out);
  return out;
}

void MatchImageQuery(ImageQuery& q, const Camera& camera, const MapDescriptors& map,
                     const ImageQueryOptions& options, const DescriptorIndex* index) {
  const auto say = [&](const std::string& what) {
    if (options.progress) options.progress(what);
  };
  say(fmt::format("{} features in {:.0f} ms; matching to {} map descriptors", q.features.size(),
                  q.times.extract_ms, map.ids.size()));
  const auto start = Clock::now();
  q.matches = index ? index->Match(q.features.descriptors, options.matching, options.threads)
                    : MatchDescriptors(q.features.descriptors, map.descriptors, options.matching);
  q.times.match_ms = MsSince(start);
  say(fmt::format("{} matches in {:.0f} ms", q.matches.size(), q.times.match_ms));
  q.query = Query{};
  q.query.cameras.push_back(camera);
  for (const DescriptorMatch& m : q.matches) {
    const SiftKeypoint& k = q.features.keypoints[m.query];
    q.query.observations.push_back(
        {0, Eigen::Vector2d(k.x, k.y), map.ids[m.map], std::nullopt, m.ratio});
  }
}

ImageQuery QueryFromImage(const std::string& image_path, const Camera& camera,
                          const MapDescriptors& map, const ImageQueryOptions& options,
                          const DescriptorIndex* index) {
  ImageQuery out = ExtractImageQuery(image_path, camera, options);
  MatchImageQuery(out, camera, map, options, index);
  return out;
}

Query CombineImageQueries(const std::vector<ImageQuery>& photos,
                          const std::vector<Rigid3d>& cam_from_rig,
                          std::span<const LocalPoint> points_local) {
  if (photos.size() != cam_from_rig.size()) {
    Fail("{} photos but {} cam_from_rig poses in the rig", photos.size(), cam_from_rig.size());
  }
  // Per photo, keypoint -> its local point (the +l methods).
  std::vector<std::unordered_map<int64_t, const LocalPoint*>> local(photos.size());
  for (size_t i = 0; i < points_local.size(); ++i) {
    const LocalPoint& p = points_local[i];
    if (p.frame < 0 || static_cast<size_t>(p.frame) >= photos.size()) {
      Fail("points_local[{}]: frame {} is not one of the {} photos", i, p.frame, photos.size());
    }
    const size_t keypoints = photos[p.frame].features.size();
    if (p.keypoint < 0 || static_cast<size_t>(p.keypoint) >= keypoints) {
      Fail("points_local[{}]: frame {} has {} keypoints, no keypoint {}", i, p.frame, keypoints,
           p.keypoint);
    }
    if (!local[p.frame].emplace(p.keypoint, &p).second) {
      Fail("points_local[{}]: frame {} keypoint {} has a local point already", i, p.frame,
           p.keypoint);
    }
  }
  Query q;
  q.cam_from_rig = cam_from_rig;
  for (size_t k = 0; k < photos.size(); ++k) {
    const ImageQuery& photo = photos[k];
    q.cameras.push_back(photo.query.cameras.at(0));
    for (size_t i = 0; i < photo.query.observations.size(); ++i) {
      QueryObservation o = photo.query.observations[i];
      o.camera = static_cast<int>(k);
      if (!points_local.empty()) {
        const auto it = local[k].find(static_cast<int64_t>(photo.matches.at(i).query));
        if (it == local[k].end()) continue;
        q.points_local.push_back(it->second->xyz);
      }
      q.observations.push_back(o);
    }
  }
  return q;
}

}  // namespace linecloud
