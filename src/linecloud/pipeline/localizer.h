// The Localizer: a map loaded once, many requests answered. It owns what
// every request needs — the lines (or, for comparison, a point model's
// points), their descriptors, the matching index and the map's gravity — and
// runs the photo path of Speciale et al. (CVPR 2019): decode (header checked
// first) → SIFT as COLMAP → match to the map's descriptors (ratio test) →
// RANSAC with the method's minimal solver → LM → success criteria.
//
// Every request method is const and safe to call from many threads at once;
// results do not depend on the thread count (fixed seeds, no global state).
// Bad input throws Error naming the photo, field or option; "no pose" is a
// result (status kNoPose with a reason), not an exception.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/features/descriptor_index.h"
#include "linecloud/features/image.h"
#include "linecloud/features/sift.h"
#include "linecloud/geometry/camera.h"
#include "linecloud/geometry/rigid3.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/pipeline/image_query.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

struct LocalizerOptions {
  // SIFT, matching (ratio test), the approximate index, the pixel cap, threads
  // (image.threads: a request's matching threads; OpenCV's extraction threads
  // are process-wide, set to it when the Localizer is made).
  ImageQueryOptions image;
  // Defaults of every request (RANSAC threshold, seed, success criteria, ...).
  LocalizeOptions localize;
  // Optional cache of the approximate index (e.g. MAP.lcm.index), authenticated
  // with `index_cache_key` (KeyStore::CacheSecret()); empty: built in memory.
  std::string index_cache;
  std::array<uint8_t, 32> index_cache_key{};
  // The map frame's gravity when the map does not store one (lift --gravity).
  std::optional<Eigen::Vector3d> map_gravity;
  std::function<void(const std::string&)> progress;  // index building

  void Check() const;
};

// The index cache policy the CLI and Python share: a map file's approximate
// index is cached in this user's cache folder (~/.cache/linecloud/index/
// HASH.index, HASH of the map's absolute path; never beside the map, a folder
// others may write into), authenticated with the key store's cache secret
// and checked against the map's descriptors when read. Sets `index_cache` /
// `index_cache_key` unless matching is exact; returns why not when there is
// no key store to authenticate with (the index is then built in memory).
std::optional<std::string> UseIndexCache(const std::string& map_path, LocalizerOptions* options);

// One photo of a request: exactly one source — the encoded file (JPEG or PNG
// bytes, as an HTTP body brings it), a decoded grey image, or features the
// caller extracted (keypoints in COLMAP's pixel convention, descriptors N×128
// in COLMAP's SIFT normalisation) — with its camera and, in a rig, its pose.
struct QueryPhoto {
  std::span<const uint8_t> encoded;
  const GreyImage* image = nullptr;
  const SiftFeatures* features = nullptr;
  Camera camera;
  Rigid3d cam_from_rig;        // rigs (several photos): this camera in the rig frame
  std::string name = "photo";  // names the photo in errors
};

// Whether photos make a rig (the m- methods): several, or one with a
// cam_from_rig other than the identity.
bool IsRig(std::span<const QueryPhoto> photos);

// Per-request settings; unset ones take the Localizer's defaults.
struct LocalizeRequest {
  // Empty: the method that uses what the request brings (MethodFor): m- for
  // several photos, +l with local points, +s when their scale is known, +u
  // with gravity here and in the map (p6L / p3P for a photo alone).
  std::string method;
  std::optional<Eigen::Vector3d> gravity;  // gravity direction in the query (rig) frame
  // The device's own 3D points (the +l methods), in the rig frame, each on
  // a keypoint of a photo; only matches on such keypoints are used. Their
  // scale is metric (scale_known: +s) or not (the pose is then a Sim(3)).
  std::vector<LocalPoint> points_local;
  std::optional<bool> scale_known;
  // This request's RANSAC, refinement and success criteria (unset: the
  // Localizer's). Front ends start from Localizer::options().localize and set
  // the request-scope options of localizer_option_table.h on it.
  std::optional<LocalizeOptions> options;
  // When the caller stops waiting (a service's request deadline): a stage
  // not started by then is skipped, RANSAC's budget ends there and the
  // colmap extractor stops between its octaves and levels (decoding and
  // matching one photo run to their end). The result is then "no pose", its
  // reason naming the stage.
  std::optional<std::chrono::steady_clock::time_point> deadline;
  int threads = 0;           // this request's matching threads (0: the Localizer's image.threads)
  bool keep_images = false;  // keep each decoded photo in the result (overlays)
  // Polled during SIFT (between its octaves and levels), once before RANSAC
  // and about every 50 ms while it runs: true
  // stops the request, whose result is then "no pose" ("stopped by the
  // caller"), e.g. Python's Ctrl-C.
  std::function<bool()> should_stop;
  // RANSAC progress (iterations, needed, best inliers, seconds) and stage messages.
  std::function<void(int, int, int, double)> ransac_progress;
  std::function<void(const std::string&)> progress;
};

enum class LocalizerStatus { kSuccess, kNoPose };

struct StageTimes {
  double decode_ms = 0, extract_ms = 0, match_ms = 0;
  double prepare_ms = 0;  // the correspondences checked, undistorted, looked up in the map
  double ransac_ms = 0, refine_ms = 0;
  double check_ms = 0;  // success checks: calibration check, uncertainty
  double total_ms = 0;  // the whole request

  // What the request spent outside its stages (the Localizer's own overhead).
  double other_ms() const {
    return total_ms - decode_ms - extract_ms - match_ms - prepare_ms - ransac_ms - refine_ms -
           check_ms;
  }
};

struct LocalizerResult {
  LocalizerStatus status = LocalizerStatus::kNoPose;
  std::string reason;  // why there is no pose
  std::string method;
  LocalizeResult pose;  // the pose (cam_from_world / rig_from_world), inliers, statistics
  Query query;          // the correspondences localized (photos: one per match)
  std::vector<ImageQuery> photos;  // per photo: features, matches, times (pixels if kept)
  StageTimes times;

  bool success() const { return status == LocalizerStatus::kSuccess; }
  size_t num_features() const;
  size_t num_matches() const;
};

class Localizer {
 public:
  // A line cloud; photos need its descriptors (lift --database). `source`
  // names the map in errors.
  Localizer(const LineCloud& cloud, const LocalizerOptions& options = {},
            const std::string& source = "map");
  // A point model, for comparison; photos need its COLMAP database.
  Localizer(const Reconstruction& model, const std::string& database,
            const LocalizerOptions& options = {}, const std::string& source = "model");
  // Any map with the descriptors its ids are matched by (none: queries only);
  // e.g. the evaluation's maps, whose lines its owner keys by point id.
  Localizer(LocalizationMap map, std::optional<MapDescriptors> descriptors,
            const LocalizerOptions& options = {}, const std::string& source = "map");

  bool lines() const;
  size_t size() const;  // lines or points
  bool has_descriptors() const;
  const std::optional<Eigen::Vector3d>& map_gravity() const;
  // The options the Localizer was made with (the defaults of its requests).
  const LocalizerOptions& options() const;
  const LocalizationMap& map() const;
  // The default method on this map for a query that is a rig (several
  // cameras, or one placed in a rig) or not, with what the request (and a
  // query file: its local points and gravity) brings.
  const MethodInfo& DefaultMethod(bool rig, const LocalizeRequest& request = {},
                                  const Query* query = nullptr) const;
  // The request's method (its own, else DefaultMethod), checked against
  // what the request brings: Error when local points are given to a method
  // that does not use them, their scale_known contradicts the method's or
  // comes without them, or a +u method lacks the query's or the map's gravity.
  const MethodInfo& RequestMethod(bool rig, const LocalizeRequest& request,
                                  const Query* query = nullptr) const;
  // RequestMethod for photos, with what photos add: a rig needs an m-
  // method, an +l method local points. What LocalizePhotos checks before
  // reading any photo (a service checks it before queueing the request).
  const MethodInfo& PhotosMethod(std::span<const QueryPhoto> photos,
                                 const LocalizeRequest& request) const;

  // Correspondences already made (QUERY.json).
  LocalizerResult LocalizeQuery(const Query& query, const LocalizeRequest& request = {},
                                std::string_view source = "query") const;
  // One photo (any source), or several photos of a rig (an m- method).
  LocalizerResult LocalizePhotos(std::span<const QueryPhoto> photos,
                                 const LocalizeRequest& request = {}) const;
  LocalizerResult LocalizeEncodedImage(std::span<const uint8_t> encoded, const Camera& camera,
                                       const LocalizeRequest& request = {},
                                       const std::string& name = "photo") const;
  LocalizerResult LocalizeImage(const GreyImage& image, const Camera& camera,
                                const LocalizeRequest& request = {}) const;
  LocalizerResult LocalizeFeatures(const SiftFeatures& features, const Camera& camera,
                                   const LocalizeRequest& request = {}) const;

  // A photo's features matched to the map (no pose): its query of
  // correspondences, with decode / extract / match times.
  ImageQuery MatchPhoto(const QueryPhoto& photo, const LocalizeRequest& request = {}) const;

 private:
  struct State;
  std::shared_ptr<const State> state_;  // shared, immutable: copies are cheap

  static std::shared_ptr<const State> MakeState(LocalizationMap map,
                                                std::optional<MapDescriptors> descriptors,
                                                std::string no_descriptors,
                                                std::optional<Eigen::Vector3d> map_gravity,
                                                const LocalizerOptions& options,
                                                const std::string& source);

  LocalizerResult Finish(const MethodInfo& method, LocalizerResult result,
                         const LocalizeRequest& request, std::string_view source,
                         std::chrono::steady_clock::time_point start) const;
  // "No pose" before the request's end: its deadline passed or its caller
  // stopped it (`reason` names the stage).
  LocalizerResult EndedEarly(const MethodInfo& method, LocalizerResult result,
                             const std::string& reason,
                             std::chrono::steady_clock::time_point start) const;
};

}  // namespace linecloud
