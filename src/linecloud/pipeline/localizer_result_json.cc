#include "linecloud/pipeline/localizer_result_json.h"

#include <vector>

#include "linecloud/localize/query_json.h"

namespace linecloud {

nlohmann::ordered_json StageTimesToJson(const StageTimes& t) {
  return {{"decode", t.decode_ms},   {"extract", t.extract_ms}, {"match", t.match_ms},
          {"prepare", t.prepare_ms}, {"ransac", t.ransac_ms},   {"refine", t.refine_ms},
          {"check", t.check_ms},     {"total", t.total_ms}};
}

nlohmann::ordered_json LocalizerResultToJson(const LocalizerResult& r, bool with_inliers) {
  nlohmann::ordered_json j = LocalizeResultToJson(FindMethod(r.method), r.pose, with_inliers);
  if (!r.success()) j["reason"] = r.reason;
  if (!r.photos.empty()) {
    std::vector<ImageOrientation> orientations;
    for (const ImageQuery& photo : r.photos) orientations.push_back(photo.image.orientation);
    AddPhotoStats(r.num_features(), r.num_matches(), r.times.decode_ms, r.times.extract_ms,
                  r.times.match_ms, r.pose, &j, orientations);
  }
  j["times_ms"] = StageTimesToJson(r.times);
  return j;
}

}  // namespace linecloud
