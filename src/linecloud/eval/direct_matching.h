// The deployable protocol: each query image's own SIFT features (OpenCV's
// extractor, or COLMAP's own with --features colmap) matched straight to the map's descriptors —
// the line cloud's for p6L, the point model's for p3P — through the Localizer that `localize
// --image` uses (the same matching rules and success criteria). The map's descriptors come from the
// map images only: the query group's images are not in its map (checked), so no query descriptor
// can reach the map it is localized against.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <vector>

#include "linecloud/eval/eval_report.h"
#include "linecloud/eval/eval_work.h"
#include "linecloud/privacy/map_lifting.h"
#include "linecloud/lifting/key.h"
#include "linecloud/pipeline/image_query.h"

namespace linecloud {

// Photos already decoded and described (SIFT), by extractor and path, without
// their pixels: `eval privacy` matches each photo to every lifting's maps and
// extracts it once.
using ExtractedPhotos = std::map<std::string, ImageQuery>;

struct DirectMatchingOptions {
  std::vector<std::string> methods = {"p6L", "p3P"};
  // Multi-camera methods run on each group with a rig: its photos, each
  // matched as above, as one generalized camera (`localize --image A --image
  // B --rig RIG.json`), against the group's rig_from_world.
  std::vector<std::string> rig_methods = {"m-p6L", "m-p3P"};
  double max_rotation_deg = 0.5;  // "localized" thresholds of [image]
  double max_translation = 0.05;  // work units (metres with ground truth)
  double threshold_px = 4.0;
  uint64_t seed = 1;
  MapLifting lifting;       // how the maps are lifted (lift's --sparsify, ...)
  ImageQueryOptions image;  // extractor, matching, index, as `localize --image`
  // When set, photos are extracted once into it and reused from it (their
  // extract_ms is the time of that one extraction).
  std::shared_ptr<ExtractedPhotos> extracted;
};

// The map's descriptors (medoid of each track) from `database`; throws Error
// when the map registers one of `excluded_images` (a query image).
MapDescriptors MapDescriptorsExcluding(const Reconstruction& map, const std::string& database,
                                       const std::vector<std::string>& excluded_images);

// A group's map as `lift --database` writes it with `lifting`: the kept
// points that have a descriptor (the medoid of the track, from the map images
// only), their lines keyed by point id, and the points themselves.
struct GroupMapData {
  LineMap lines;
  PointMap points;
  MapDescriptors descriptors;
};
GroupMapData LoadGroupMapData(const std::string& work_dir, const EvalGroup& group,
                              const LiftingKey& key, const MapLifting& lifting);

// report.json's "direct_matching": per method the queries, localized count,
// median errors and mean stage times, per query (image) and per rig the
// details. Throws Error on a rig method that is not a multi-camera one or
// needs local points (+l: photos give none).
DirectMatchingReport RunDirectMatching(const EvalWork& work, const std::string& work_dir,
                                       const LiftingKey& key, const DirectMatchingOptions& options);

// Photos of another place: each query photo of `photos` (a work of another
// scene) matched and localized against the first group's map of `map_work`,
// as RunDirectMatching does. Every success is a wrong pose; per_query's rows
// name the photo, `group` the map's scene.
DirectMatchingReport RunOtherPlace(const EvalWork& photos, const EvalWork& map_work,
                                   const std::string& map_work_dir, const LiftingKey& key,
                                   const DirectMatchingOptions& options);

}  // namespace linecloud
