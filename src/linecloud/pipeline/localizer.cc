#include "linecloud/pipeline/localizer.h"

#include <algorithm>
#include <numeric>
#include <unordered_map>
#include <chrono>
#include <cmath>

#include <filesystem>

#include <fmt/format.h>
#include <sodium.h>

#include "linecloud/features/sift_opencv.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/key_store.h"
#include "linecloud/util/file.h"
#include "linecloud/util/clock.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

using Clock = std::chrono::steady_clock;

// Client features: finite keypoints inside the camera's image, 128 bytes each.
// The median L1 norm of the descriptors (bytes summed): COLMAP's RootSIFT
// (square roots of an L1-normalised histogram, times 512) puts it near 4 500
// (fountain 0000.jpg: 5th-95th percentile of single descriptors 3 853-5 020);
// L2-normalised SIFT cast to bytes (OpenCV's, as `descriptors.astype(uint8)`)
// near 3 400 (2 763-3 868). Such descriptors matched a RootSIFT map poorly and
// silently: 146 inliers where RootSIFT gave 479.
constexpr double kMinRootSiftL1 = 4000;

double MedianDescriptorL1(const SiftFeatures& f) {
  std::vector<double> l1(f.keypoints.size());
  for (size_t i = 0; i < l1.size(); ++i) {
    const uint8_t* d = f.descriptors.data() + 128 * i;
    l1[i] = std::accumulate(d, d + 128, 0.0);
  }
  std::nth_element(l1.begin(), l1.begin() + static_cast<std::ptrdiff_t>(l1.size() / 2), l1.end());
  return l1[l1.size() / 2];
}

void CheckFeatures(const SiftFeatures& f, const Camera& camera, const std::string& name) {
  if (f.descriptors.size() != 128 * f.keypoints.size()) {
    Fail("{}: {} keypoints but {} descriptor bytes (expected {} x 128)", name, f.keypoints.size(),
         f.descriptors.size(), f.keypoints.size());
  }
  if (f.keypoints.size() >= 32) {
    if (const double l1 = MedianDescriptorL1(f); l1 < kMinRootSiftL1) {
      Fail(
          "{}: the descriptors look like L2-normalised SIFT (OpenCV's, cast to bytes: median sum "
          "{:.0f}, where COLMAP's RootSIFT gives about 4 500), which match this map's RootSIFT "
          "descriptors poorly; convert each: d = 512 * sqrt(d / sum(d)), rounded and clipped to "
          "0-255 (RootSIFT; in Python linecloud.interop.from_opencv_sift), or send the photo",
          name, l1);
    }
  }
  for (size_t i = 0; i < f.keypoints.size(); ++i) {
    const SiftKeypoint& k = f.keypoints[i];
    if (!std::isfinite(k.x) || !std::isfinite(k.y) || k.x < 0 || k.y < 0 ||
        k.x > static_cast<double>(camera.width) || k.y > static_cast<double>(camera.height)) {
      Fail("{}: keypoints[{}] = ({}, {}) is not a pixel of the {}x{} camera", name, i, k.x, k.y,
           camera.width, camera.height);
    }
  }
}

// A request's local points before any photo is read: each on a photo of the
// request, finite, on a keypoint the photo has when its features are given
// (an extracted photo's keypoints are counted after SIFT).
void CheckLocalPoints(std::span<const LocalPoint> points, std::span<const QueryPhoto> photos) {
  for (size_t i = 0; i < points.size(); ++i) {
    const LocalPoint& p = points[i];
    if (p.frame < 0 || static_cast<size_t>(p.frame) >= photos.size()) {
      Fail("points_local[{}]: frame {} is not one of the {} photos", i, p.frame, photos.size());
    }
    if (!p.xyz.allFinite()) Fail("points_local[{}]: xyz must be finite", i);
    const SiftFeatures* f = photos[p.frame].features;
    if (p.keypoint < 0 || (f && static_cast<size_t>(p.keypoint) >= f->size())) {
      Fail("points_local[{}]: {} has {} keypoints, no keypoint {}", i, photos[p.frame].name,
           f ? f->size() : 0, p.keypoint);
    }
  }
}

// A single photo of a request, its source still to be set.
QueryPhoto OnePhoto(const Camera& camera, const std::string& name) {
  QueryPhoto photo;
  photo.camera = camera;
  photo.name = name;
  return photo;
}

// A rig's photos are different photos: one sent twice would count its
// matches twice (a pose as confident as two views would make it, from one).
// Refused when two photos bring the same bytes, pixels or descriptors.
void CheckDistinctPhotos(std::span<const QueryPhoto> photos) {
  auto same = [](const QueryPhoto& a, const QueryPhoto& b) -> const char* {
    if (!a.encoded.empty() && a.encoded.size() == b.encoded.size() &&
        std::equal(a.encoded.begin(), a.encoded.end(), b.encoded.begin())) {
      return "bytes";
    }
    if (a.image && b.image && a.image->width == b.image->width &&
        a.image->height == b.image->height && a.image->pixels == b.image->pixels) {
      return "pixels";
    }
    if (a.features && b.features && !a.features->descriptors.empty() &&
        a.features->descriptors == b.features->descriptors) {
      return "descriptors";
    }
    return nullptr;
  };
  for (size_t j = 1; j < photos.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      if (const char* what = same(photos[i], photos[j])) {
        Fail(
            "{} is {} again (the same {}): a rig's photos must be different photos, a repeated "
            "one would count its matches twice",
            photos[j].name, photos[i].name, what);
      }
    }
  }
}

// The same photo re-encoded, shuffled or trimmed passes CheckDistinctPhotos
// but matches the same map points at the same pixels. Two photos of a rig are
// one view twice when most matches of one (at least 20, and half of the
// smaller photo's) find a match of the other to the same map point within
// half a pixel: a second camera, or the same camera having moved, puts them
// elsewhere.
void CheckDistinctViews(std::span<const ImageQuery> photos, std::span<const QueryPhoto> sources) {
  std::vector<std::unordered_multimap<uint64_t, Eigen::Vector2d>> by_id(photos.size());
  for (size_t k = 0; k < photos.size(); ++k) {
    for (const QueryObservation& o : photos[k].query.observations) by_id[k].emplace(o.id, o.xy);
  }
  for (size_t j = 1; j < photos.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      size_t same = 0;
      for (const QueryObservation& o : photos[j].query.observations) {
        const auto [begin, end] = by_id[i].equal_range(o.id);
        same +=
            std::any_of(begin, end, [&](const auto& e) { return (e.second - o.xy).norm() < 0.5; });
      }
      const size_t smaller =
          std::min(photos[i].query.observations.size(), photos[j].query.observations.size());
      if (same >= 20 && 2 * same >= smaller) {
        Fail(
            "{} shows what {} shows ({} of its {} matches are the other's, at the same pixels): a "
            "rig's photos must be different views, a repeated one would count its matches twice",
            sources[j].name, sources[i].name, same, photos[j].query.observations.size());
      }
    }
  }
}

}  // namespace

bool IsRig(std::span<const QueryPhoto> photos) {
  return photos.size() > 1 || (photos.size() == 1 && !photos[0].cam_from_rig.IsIdentity());
}

struct Localizer::State {
  std::string source;
  LocalizationMap map;
  std::optional<MapDescriptors> descriptors;
  std::string no_descriptors;  // why photos cannot be matched, when no descriptors
  std::unique_ptr<DescriptorIndex> index;
  std::optional<Eigen::Vector3d> gravity;
  LocalizerOptions options;

  // The approximate index of large maps: loaded from the cache when it is this
  // user's and current, else built (and cached when a cache path is given).
  void BuildIndex() {
    const ImageQueryOptions& o = options.image;
    if (!descriptors || o.approximate_from == 0 || descriptors->ids.size() < o.approximate_from ||
        o.matching.cross_check) {
      return;
    }
    if (!options.index_cache.empty()) {
      index = DescriptorIndex::Load(options.index_cache, descriptors->descriptors, o.index,
                                    options.index_cache_key);
      if (index) return;
    }
    if (options.progress) {
      options.progress(fmt::format("building the descriptor index of {} map descriptors",
                                   descriptors->ids.size()));
    }
    index = std::make_unique<DescriptorIndex>(descriptors->descriptors, o.index);
    if (options.index_cache.empty()) return;
    try {
      index->Save(options.index_cache, options.index_cache_key);
    } catch (const Error& e) {
      if (options.progress) options.progress(std::string("index not cached: ") + e.what());
    }
  }
};

std::optional<std::string> UseIndexCache(const std::string& map_path, LocalizerOptions* options) {
  if (options->image.approximate_from == 0) return std::nullopt;  // exact matching: no index
  try {
    options->index_cache_key = KeyStore(KeyStore::DefaultDirectory()).CacheSecret();
  } catch (const Error& e) {
    return std::string("descriptor index not cached: ") + e.what();
  }
  std::error_code ec;
  const std::string abs = std::filesystem::absolute(map_path, ec).lexically_normal().string();
  EnsureSodiumInitialized();
  std::array<uint8_t, 16> hash;
  crypto_generichash(hash.data(), hash.size(), reinterpret_cast<const unsigned char*>(abs.data()),
                     abs.size(), nullptr, 0);
  options->index_cache = JoinPaths(UserCacheDirectory("index"), ToHex(hash) + ".index");
  return std::nullopt;
}

void LocalizerOptions::Check() const {
  image.sift.Check();
  image.matching.Check();
  image.index.Check();
  if (image.threads < 1) Fail("threads must be at least 1, got {}", image.threads);
  localize.Check();
  if (map_gravity && !(map_gravity->allFinite() && map_gravity->norm() > 0)) {
    Fail("map gravity must be a finite non-zero direction");
  }
}

size_t LocalizerResult::num_features() const {
  size_t n = 0;
  for (const ImageQuery& p : photos) n += p.features.size();
  return n;
}

size_t LocalizerResult::num_matches() const {
  size_t n = 0;
  for (const ImageQuery& p : photos) n += p.matches.size();
  return n;
}

std::shared_ptr<const Localizer::State> Localizer::MakeState(
    LocalizationMap map, std::optional<MapDescriptors> descriptors, std::string no_descriptors,
    std::optional<Eigen::Vector3d> map_gravity, const LocalizerOptions& options,
    const std::string& source) {
  if (descriptors && descriptors->descriptors.size() != 128 * descriptors->ids.size()) {
    Fail("{}: {} descriptor ids but {} descriptor bytes (expected 128 each)", source,
         descriptors->ids.size(), descriptors->descriptors.size());
  }
  // OpenCV's extraction threads are process-wide (sift_opencv.h).
  if (options.image.sift.extractor == SiftExtractor::kOpenCV)
    SetOpenCVThreads(options.image.threads);
  auto state = std::make_shared<State>();
  state->source = source;
  state->options = options;
  state->map = std::move(map);
  state->descriptors = std::move(descriptors);
  if (!state->descriptors) state->no_descriptors = std::move(no_descriptors);
  // The options' gravity wins over the one the map stores.
  state->gravity = options.map_gravity ? options.map_gravity->normalized() : map_gravity;
  state->BuildIndex();
  return state;
}

Localizer::Localizer(const LineCloud& cloud, const LocalizerOptions& options,
                     const std::string& source) {
  options.Check();
  state_ = MakeState(
      LineMapFromCloud(cloud),
      cloud.has_descriptors() ? std::optional(MapDescriptorsFromCloud(cloud, source))
                              : std::nullopt,
      fmt::format(
          "{}: the map has no descriptors to match a photo to; lift it with the model's COLMAP "
          "database",
          source),
      cloud.gravity, options, source);
}

Localizer::Localizer(const Reconstruction& model, const std::string& database,
                     const LocalizerOptions& options, const std::string& source) {
  options.Check();
  state_ = MakeState(
      PointMapFromModel(model),
      database.empty() ? std::nullopt : std::optional(MapDescriptorsFromModel(model, database)),
      fmt::format("{}: photos need the model's COLMAP database", source), std::nullopt, options,
      source);
}

Localizer::Localizer(LocalizationMap map, std::optional<MapDescriptors> descriptors,
                     const LocalizerOptions& options, const std::string& source) {
  options.Check();
  state_ = MakeState(std::move(map), std::move(descriptors),
                     source + ": the map has no descriptors", std::nullopt, options, source);
}

bool Localizer::lines() const { return std::holds_alternative<LineMap>(state_->map); }

size_t Localizer::size() const {
  return std::visit(
      [](const auto& m) -> size_t {
        if constexpr (std::is_same_v<std::decay_t<decltype(m)>, LineMap>) {
          return m.lines.size();
        } else {
          return m.points.size();
        }
      },
      state_->map);
}

bool Localizer::has_descriptors() const { return state_->descriptors.has_value(); }

const std::optional<Eigen::Vector3d>& Localizer::map_gravity() const { return state_->gravity; }

const LocalizationMap& Localizer::map() const { return state_->map; }

const LocalizerOptions& Localizer::options() const { return state_->options; }

const MethodInfo& Localizer::DefaultMethod(bool rig, const LocalizeRequest& request,
                                           const Query* query) const {
  const bool local = !request.points_local.empty() || (query && !query->points_local.empty());
  const bool query_gravity = request.gravity || (query && query->gravity_query);
  const bool map_gravity = state_->gravity || (query && query->gravity_map);
  return MethodFor({.lines = lines(),
                    .several_cameras = rig,
                    .local_points = local,
                    .known_scale = local && request.scale_known.value_or(false),
                    .gravity = query_gravity && map_gravity});
}

const MethodInfo& Localizer::RequestMethod(bool rig, const LocalizeRequest& request,
                                           const Query* query) const {
  const MethodInfo& m =
      request.method.empty() ? DefaultMethod(rig, request, query) : FindMethod(request.method);
  if (!m.local_points && !request.points_local.empty()) {
    Fail(
        "points_local: {} does not use the query's own points (the +l methods do: m-P4L+l, "
        "m-P3L+l+u, m-P3L+l+s, m-P2L+l+u+s)",
        m.name);
  }
  if (request.scale_known && request.points_local.empty() &&
      !(query && !query->points_local.empty())) {
    Fail("scale_known is the scale of the local points: it goes with points_local");
  }
  if (m.local_points && request.scale_known && *request.scale_known != m.known_scale) {
    Fail("scale_known is {} but {} {} the scale", *request.scale_known ? "true" : "false", m.name,
         m.known_scale ? "takes the local points' as known" : "estimates");
  }
  if (m.gravity && !request.gravity && !(query && query->gravity_query)) {
    Fail("{} needs the gravity direction in the query's frame (gravity)", m.name);
  }
  if (m.gravity && !state_->gravity && !(query && query->gravity_map)) {
    Fail(
        "{} needs the map's gravity direction, which this map has none of (lift --gravity, or "
        "the map option map_gravity)",
        m.name);
  }
  return m;
}

const MethodInfo& Localizer::PhotosMethod(std::span<const QueryPhoto> photos,
                                          const LocalizeRequest& request) const {
  if (photos.empty()) Fail("no photo given");
  const bool rig = IsRig(photos);
  const MethodInfo& method = RequestMethod(rig, request);
  if (rig && !method.multi) {
    if (photos.size() > 1) {
      Fail("{} photos make one generalized camera: use an m- method (m-p6L, m-p3P, ...), not {}",
           photos.size(), method.name);
    }
    Fail("{} has a cam_from_rig: a photo in a rig needs an m- method (m-p6L, m-p3P, ...), not {}",
         photos[0].name, method.name);
  }
  if (method.local_points && request.points_local.empty()) {
    Fail("{} localizes the photos' own 3D points: give points_local (frame, keypoint, xyz)",
         method.name);
  }
  CheckLocalPoints(request.points_local, photos);
  CheckDistinctPhotos(photos);
  CheckMethodAndMap(method, state_->map);
  return method;
}

LocalizerResult Localizer::LocalizeQuery(const Query& query, const LocalizeRequest& request,
                                         std::string_view source) const {
  const auto start = Clock::now();
  if (!request.points_local.empty()) {
    Fail("{}: a query file brings its own points_local (one per observation)", source);
  }
  LocalizerResult result;
  result.query = query;
  const bool rig =
      query.cameras.size() > 1 || std::any_of(query.cam_from_rig.begin(), query.cam_from_rig.end(),
                                              [](const Rigid3d& p) { return !p.IsIdentity(); });
  const MethodInfo& method = RequestMethod(rig, request, &query);
  return Finish(method, std::move(result), request, source, start);
}

ImageQuery Localizer::MatchPhoto(const QueryPhoto& photo, const LocalizeRequest& request) const {
  const int sources =
      int{!photo.encoded.empty()} + int{photo.image != nullptr} + int{photo.features != nullptr};
  if (sources != 1) {
    Fail("{}: give exactly one of the encoded photo, a decoded image or its features", photo.name);
  }
  if (!state_->descriptors) Fail("{}", state_->no_descriptors);
  photo.camera.Check(photo.name + ": camera");
  ImageQueryOptions o = state_->options.image;
  o.progress = request.progress;
  if (request.threads < 0) Fail("{}: threads must not be negative", photo.name);
  if (request.threads > 0) o.threads = request.threads;
  o.sift.deadline = request.deadline;
  o.sift.should_stop = request.should_stop;  // polled between its octaves and levels
  ImageQuery q;
  if (photo.features) {
    CheckFeatures(*photo.features, photo.camera, photo.name);
    q.features = *photo.features;
  } else {
    const GreyImage* grey = photo.image;
    if (!grey) {
      const auto start = Clock::now();
      q.image = DecodeGreyImage(photo.encoded, photo.name, PhotoLimits(photo.camera, o));
      q.times.decode_ms = MsSince(start);
      grey = &q.image;
    } else if (static_cast<uint64_t>(grey->width) != photo.camera.width ||
               static_cast<uint64_t>(grey->height) != photo.camera.height ||
               grey->pixels.size() != static_cast<size_t>(grey->width) * grey->height) {
      Fail("{}: the image is {}x{} pixels but the camera is {}x{}", photo.name, grey->width,
           grey->height, photo.camera.width, photo.camera.height);
    }
    ExtractImageFeatures(*grey, photo.name, o, &q);
    if (request.keep_images && photo.image) q.image = *photo.image;
    if (!request.keep_images) q.image.pixels = {};  // its size and orientation stay
  }
  if (request.deadline && Clock::now() >= *request.deadline) {
    throw DeadlinePassed(
        fmt::format("the request's deadline passed before matching {}", photo.name));
  }
  MatchImageQuery(q, photo.camera, *state_->descriptors, o, state_->index.get());
  return q;
}

LocalizerResult Localizer::LocalizePhotos(std::span<const QueryPhoto> photos,
                                          const LocalizeRequest& request) const {
  const auto start = Clock::now();
  // Before decoding and matching (seconds for nothing).
  const MethodInfo& method = PhotosMethod(photos, request);
  LocalizerResult result;
  std::vector<Rigid3d> rig;
  for (const QueryPhoto& photo : photos) {
    if (request.deadline && Clock::now() >= *request.deadline) {
      return EndedEarly(method, std::move(result),
                        "the request's deadline passed before reading " + photo.name, start);
    }
    try {
      result.photos.push_back(MatchPhoto(photo, request));
    } catch (const DeadlinePassed& e) {
      return EndedEarly(method, std::move(result), e.what(), start);
    }
    rig.push_back(photo.cam_from_rig);
    const ImageQueryTimes& t = result.photos.back().times;
    result.times.decode_ms += t.decode_ms;
    result.times.extract_ms += t.extract_ms;
    result.times.match_ms += t.match_ms;
  }
  if (photos.size() > 1) CheckDistinctViews(result.photos, photos);
  result.query = !IsRig(photos) && request.points_local.empty()
                     ? result.photos[0].query
                     : CombineImageQueries(result.photos, rig, request.points_local);
  return Finish(method, std::move(result), request, photos[0].name, start);
}

LocalizerResult Localizer::LocalizeEncodedImage(std::span<const uint8_t> encoded,
                                                const Camera& camera,
                                                const LocalizeRequest& request,
                                                const std::string& name) const {
  if (encoded.empty()) Fail("{}: empty file, not an image", name);
  QueryPhoto photo = OnePhoto(camera, name);
  photo.encoded = encoded;
  return LocalizePhotos(std::span(&photo, 1), request);
}

LocalizerResult Localizer::LocalizeImage(const GreyImage& image, const Camera& camera,
                                         const LocalizeRequest& request) const {
  QueryPhoto photo = OnePhoto(camera, "image");
  photo.image = &image;
  return LocalizePhotos(std::span(&photo, 1), request);
}

LocalizerResult Localizer::LocalizeFeatures(const SiftFeatures& features, const Camera& camera,
                                            const LocalizeRequest& request) const {
  QueryPhoto photo = OnePhoto(camera, "features");
  photo.features = &features;
  return LocalizePhotos(std::span(&photo, 1), request);
}

LocalizerResult Localizer::EndedEarly(const MethodInfo& method, LocalizerResult result,
                                      const std::string& reason, Clock::time_point start) const {
  result.method = method.name;
  result.status = LocalizerStatus::kNoPose;
  result.reason = reason;
  result.pose.failure = result.reason;
  result.times.total_ms = MsSince(start);
  return result;
}

LocalizerResult Localizer::Finish(const MethodInfo& method, LocalizerResult result,
                                  const LocalizeRequest& request, std::string_view source,
                                  Clock::time_point start) const {
  result.method = method.name;
  Query& query = result.query;
  // Gravity: the request's for the query frame (a query file's own wins), the
  // map's from the .lcm or the options.
  if (request.gravity && !query.gravity_query) {
    const Eigen::Vector3d& g = *request.gravity;
    if (!(g.allFinite() && g.cwiseAbs().maxCoeff() > 0)) {
      Fail("gravity must be a finite non-zero direction x,y,z");
    }
    query.gravity_query = (g / g.cwiseAbs().maxCoeff()).normalized();  // no overflow for 1e308
  }
  if (!query.gravity_map && state_->gravity) query.gravity_map = state_->gravity;
  LocalizeOptions options = request.options.value_or(state_->options.localize);
  if (request.options) options.Check();
  bool deadline_budget = false;  // RANSAC's time cut to the request's deadline
  if (request.deadline) {
    const double left = std::chrono::duration<double>(*request.deadline - Clock::now()).count();
    if (left <= 0)
      return EndedEarly(method, std::move(result), "the request's deadline passed before RANSAC",
                        start);
    if (options.ransac.max_seconds <= 0 || options.ransac.max_seconds > left) {
      options.ransac.max_seconds = left;
      deadline_budget = true;
    }
  }
  if (request.ransac_progress) options.ransac.progress = request.ransac_progress;
  if (request.should_stop) {
    if (request.should_stop()) {
      return EndedEarly(method, std::move(result), "stopped by the caller before RANSAC", start);
    }
    options.ransac.should_stop = request.should_stop;
  }
  if (!result.photos.empty() &&
      query.observations.size() < static_cast<size_t>(method.sample_size)) {
    // Too few matches for one sample: no pose (a photo of something else).
    result.pose.num_correspondences = static_cast<int>(query.observations.size());
    result.pose.failure = fmt::format("{} matches, fewer than the {} the method's sample needs",
                                      query.observations.size(), method.sample_size);
  } else {
    result.pose = Localize(method, query, state_->map, options, source);
    if (deadline_budget && result.pose.success &&
        std::string_view(result.pose.stats.stop_reason) == "max_seconds") {
      // The deadline, not the search's own stop, ended RANSAC: the pose was
      // never confirmed (a request asking for no support at all drew junk
      // until the deadline and got a "success" of 17 chance inliers).
      result.pose.success = false;
      result.pose.failure =
          "the request's deadline ended RANSAC's search before it could confirm a pose";
    }
  }
  result.status = result.pose.success ? LocalizerStatus::kSuccess : LocalizerStatus::kNoPose;
  result.reason = result.pose.failure;
  result.times.prepare_ms = result.pose.prepare_ms;
  result.times.ransac_ms = result.pose.stats.ransac_ms;
  result.times.refine_ms = result.pose.refine_ms;
  result.times.check_ms = result.pose.check_ms;
  result.times.total_ms = MsSince(start);
  return result;
}

}  // namespace linecloud
