// A query from a photo: decode, SIFT as COLMAP computes it, match to the map's
// descriptors — the correspondences `Localize` takes (Speciale et al., CVPR
// 2019: the query's local features matched to the descriptors stored with the
// lines). The map side is a line cloud lifted with descriptors, or a point
// model with its COLMAP database.
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "linecloud/features/descriptor_index.h"
#include "linecloud/features/matching.h"
#include "linecloud/features/sift.h"
#include "linecloud/geometry/camera.h"
#include "linecloud/io/colmap_model.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

// The descriptors a query is matched to, with the id each belongs to (a line
// id for a line cloud, a point id for a point model).
struct MapDescriptors {
  std::vector<uint64_t> ids;
  std::vector<uint8_t> descriptors;  // ids.size() x 128
};

// Throws Error naming `source` when the cloud has no descriptors ("lift with
// --database") or descriptors of another type or size than COLMAP's SIFT.
MapDescriptors MapDescriptorsFromCloud(const LineCloud& cloud, const std::string& source);
// One descriptor per point of the model that has one in the database.
MapDescriptors MapDescriptorsFromModel(const Reconstruction& model, const std::string& database);

// "MODEL WIDTH HEIGHT PARAMS..." in COLMAP's cameras.txt order, e.g.
// "PINHOLE 1536 1024 1520.4 1525.9 768 512"; throws Error on an unknown model
// or a wrong parameter count, naming `what` (the CLI's flag, the request's part).
Camera ParseCameraString(const std::string& text, const std::string& what = "--camera");

// "x,y,z" (a direction, e.g. --gravity); throws Error naming `option` on
// anything else, a non-finite or a zero vector. Returns it normalised.
Eigen::Vector3d ParseDirection(const std::string& text, const std::string& option);

struct ImageQueryOptions {
  SiftOptions sift;
  DescriptorMatchOptions matching;
  // Maps with at least this many descriptors are matched through the
  // approximate index (DescriptorIndex; the Localizer builds it once), smaller
  // ones exactly; 0: always exact. The index wins from a few thousand
  // descriptors on (recall 1.000 at 12 800: docs/fast_photo.md).
  size_t approximate_from = 4096;
  DescriptorIndexOptions index;  // its kind, cells probed, build threads
  // Threads of one photo's matching (and, through SetOpenCVThreads, of the
  // OpenCV extractor); the matches do not depend on it.
  int threads = 1;
  // Photos whose header announces more pixels are refused before decoding.
  uint64_t max_pixels = 50'000'000;
  std::function<void(const std::string&)> progress;  // stage messages
};

struct ImageQueryTimes {
  double decode_ms = 0, extract_ms = 0, match_ms = 0;
};

struct ImageQuery {
  GreyImage image;  // the decoded photo (for drawing on it)
  Query query;      // one camera, one observation per match
  SiftFeatures features;
  std::vector<DescriptorMatch> matches;  // query = keypoint index, map = MapDescriptors row
  ImageQueryTimes times;
};

// Throws Error naming the image when it cannot be read or its size differs
// from the camera's.
// `index`, when given, matches instead of the exact search.
// QueryFromImage = ExtractImageQuery + MatchImageQuery; the two halves let a
// caller that matches one photo to several maps extract it once.
ImageQuery ExtractImageQuery(const std::string& image_path, const Camera& camera,
                             const ImageQueryOptions& options);
// The limits a photo for `camera` is decoded under: the camera's size and
// the pixel cap, both checked on the header (ReadImageHeader).
ImageLimits PhotoLimits(const Camera& camera, const ImageQueryOptions& options);
// SIFT of a decoded photo into q->features, timed (extract_ms), with a
// progress message naming `name`.
void ExtractImageFeatures(const GreyImage& image, const std::string& name,
                          const ImageQueryOptions& options, ImageQuery* q);
// Matches `q`'s features to `map` and sets its matches, query and match time
// (any earlier ones are replaced).
void MatchImageQuery(ImageQuery& q, const Camera& camera, const MapDescriptors& map,
                     const ImageQueryOptions& options, const DescriptorIndex* index = nullptr);
ImageQuery QueryFromImage(const std::string& image_path, const Camera& camera,
                          const MapDescriptors& map, const ImageQueryOptions& options,
                          const DescriptorIndex* index = nullptr);

// Several photos of a calibrated rig (or of a short trajectory whose relative
// poses are known) as one query for the m- methods: camera k is photo k, with
// cam_from_rig[k]. With `points_local` (the +l methods) only the matches of
// keypoints with a local point are kept, each with its X̃. Throws Error when
// the counts differ or a local point names a keypoint its photo lacks.
Query CombineImageQueries(const std::vector<ImageQuery>& photos,
                          const std::vector<Rigid3d>& cam_from_rig,
                          std::span<const LocalPoint> points_local = {});

}  // namespace linecloud
