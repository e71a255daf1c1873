// What a picture of one photo's localization shows (the CLI's --overlay, the
// console's overlay for the map's owner): every correspondence's keypoint,
// inlier or outlier, and for each inlier where the estimated pose puts its map
// feature — a short segment of the projected line through the point of the
// line nearest the keypoint's ray (line cloud), or the segment from the
// keypoint to the projected point (point model).
#pragma once

#include <optional>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "linecloud/localize/localize.h"

namespace linecloud {

struct OverlayMark {
  Eigen::Vector2d keypoint;  // pixels, COLMAP convention (as QueryObservation::xy)
  bool inlier = false;
  // Inliers with a pose whose feature projects in front of the camera: its segment (pixels).
  std::optional<std::pair<Eigen::Vector2d, Eigen::Vector2d>> feature;
};

// The segments of projected lines are 2 * `half_length` pixels long. `query`
// has one camera and `result` is Localize's on `query` and `map`; throws Error
// otherwise.
std::vector<OverlayMark> OverlayMarks(const Query& query, const LocalizeResult& result,
                                      const LocalizationMap& map, double half_length);

// The segments' half length the overlays use for a photo `width` pixels wide.
double OverlaySegmentHalfLength(int width);

}  // namespace linecloud
