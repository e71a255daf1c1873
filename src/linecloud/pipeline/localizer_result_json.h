// The one JSON form of a Localizer's result, written by the command line
// (`localize`'s output), Python (the Localizer's result dict) and, its
// pose-only part, the service: localize's fields (LocalizeResultToJson),
// the photos' num_features / num_matches / orientation, and times_ms with
// every stage of StageTimes.
#pragma once

#include <nlohmann/json.hpp>

#include "linecloud/pipeline/localizer.h"

namespace linecloud {

// {"decode", "extract", "match", "prepare", "ransac", "refine", "check", "total"} in ms.
nlohmann::ordered_json StageTimesToJson(const StageTimes& times);

nlohmann::ordered_json LocalizerResultToJson(const LocalizerResult& result, bool with_inliers);

}  // namespace linecloud
