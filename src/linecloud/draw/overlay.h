// The picture that shows a person at a glance whether a photo's pose is
// right: the photo (grey), every correspondence's keypoint — inliers sky blue,
// outliers vermilion (Okabe and Ito's colour-blind-safe pair) — and, for the
// inliers, in yellow, where the estimated pose puts their
// map features: a short segment of the projected line (line cloud) or the
// projected point joined to the keypoint (point model).
#pragma once

#include <string>

#include "linecloud/features/image.h"
#include "linecloud/localize/localize.h"

namespace linecloud {

// `query` has one camera; `result` is Localize's on `query` and `map`.
// Throws Error naming `path` when the PNG cannot be written.
void WriteLocalizationOverlay(const std::string& path, const GreyImage& photo, const Query& query,
                              const LocalizeResult& result, const LocalizationMap& map);

}  // namespace linecloud
