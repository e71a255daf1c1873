// QUERY.json of `linecloud localize` (docs/formats.md) and its result JSON.
#pragma once

#include <optional>
#include <span>
#include <string>

#include <nlohmann/json.hpp>

#include "linecloud/features/image.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

// A camera dict {"model", "width", "height", "params"} (COLMAP's model names
// and parameter order); throws Error naming `where` and the field.
Camera CameraFromJson(const nlohmann::json& j, const std::string& where);
nlohmann::json CameraToJson(const Camera& camera);

// Throws Error naming `source` and the field on any malformed entry.
Query ParseQueryJson(const nlohmann::json& j, const std::string& source);
Query ReadQueryJson(const std::string& path);

nlohmann::json QueryToJson(const Query& query);

// A rig's local points (+l methods): [{"frame": k, "keypoint": i, "xyz": [x,
// y, z]}, ...] (LocalPoint). Throws Error naming `where`, the entry and the
// field.
std::vector<LocalPoint> ParseLocalPointsJson(const nlohmann::json& j, const std::string& where);
nlohmann::json LocalPointsToJson(std::span<const LocalPoint> points);

// RIG.json: what a device knows of its frames besides their photos —
// {"cam_from_rig": [{"q": [w, x, y, z], "t": [x, y, z]}, ...] (one pose per
// photo), "points_local"?: [...] (above), "scale_known"?: bool,
// "gravity"?: [x, y, z] (rig frame)}. Throws Error naming the file and the field.
struct RigFile {
  std::vector<Rigid3d> cam_from_rig;
  std::vector<LocalPoint> points_local;
  std::optional<bool> scale_known;
  std::optional<Eigen::Vector3d> gravity;
};
RigFile ParseRigJson(const nlohmann::json& j, const std::string& where);
RigFile ReadRigJson(const std::string& path);

// The pose and a summary first — {"method", "success", "reason" (failures),
// "q", "t", "scale", "center", "num_correspondences", "num_inliers",
// "inlier_ratio", "uncertainty", "stats"} — then "inliers" (observation
// indices) only when `with_inliers`.
nlohmann::ordered_json LocalizeResultToJson(const MethodInfo& method, const LocalizeResult& result,
                                            bool with_inliers = true);

// Adds a photo query's num_features, num_matches and times_ms (decode,
// extract, match, RANSAC, refine) to a result, and "orientation" (per photo:
// its EXIF orientation and whether it was applied) when a photo has one.
void AddPhotoStats(size_t num_features, size_t num_matches, double decode_ms, double extract_ms,
                   double match_ms, const LocalizeResult& result, nlohmann::ordered_json* j,
                   std::span<const ImageOrientation> orientations = {});

// One line of COLMAP's images.txt for the pose (cam_from_world):
// IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME, followed by an empty
// points2D line, so that the pose drops into COLMAP's tools.
std::string LocalizeResultToColmapImagesTxt(const LocalizeResult& result, const std::string& name,
                                            uint32_t image_id = 1, uint32_t camera_id = 1);

}  // namespace linecloud
