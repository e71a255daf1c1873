#include "linecloud/io/problem_json.h"

#include <cstdint>
#include <limits>

#include "linecloud/io/json_util.h"
#include "linecloud/util/error.h"

namespace linecloud {

MinimalProblem ParseProblemJson(const nlohmann::json& j, const std::string& source) {
  if (!j.is_object()) Fail("{}: expected a JSON object", source);
  if (!j.contains("method") || !j["method"].is_string()) {
    Fail("{}: field 'method' (string) is missing", source);
  }
  MinimalProblem p;
  p.method = &FindMethod(j["method"].get<std::string>());
  MinimalSample& s = p.sample;
  const auto field = [&](const char* name) { return source + ": " + name; };
  if (j.contains("bearings")) s.bearings = JsonVector3List(j["bearings"], field("bearings"));
  if (j.contains("points")) s.points = JsonVector3List(j["points"], field("points"));
  if (j.contains("points_local")) {
    s.points_local = JsonVector3List(j["points_local"], field("points_local"));
  }
  if (j.contains("lines")) s.lines = JsonLineList(j["lines"], field("lines"));
  if (j.contains("camera_index")) {
    const auto& ci = j["camera_index"];
    if (!ci.is_array()) Fail("{}: expected an array of integers", field("camera_index"));
    for (size_t i = 0; i < ci.size(); ++i) {
      // Range-checked: 4294967296 must not wrap to camera 0.
      if (!ci[i].is_number_integer() || ci[i].get<int64_t>() < 0 ||
          ci[i].get<int64_t>() > std::numeric_limits<int>::max()) {
        Fail("{}[{}]: expected a camera index (a non-negative integer)", field("camera_index"), i);
      }
      s.camera_index.push_back(static_cast<int>(ci[i].get<int64_t>()));
    }
  }
  if (j.contains("cam_from_rig")) {
    const auto& cr = j["cam_from_rig"];
    if (!cr.is_array()) Fail("{}: expected an array of poses", field("cam_from_rig"));
    for (size_t i = 0; i < cr.size(); ++i) {
      s.cam_from_rig.push_back(
          JsonPose(cr[i], field("cam_from_rig") + "[" + std::to_string(i) + "]"));
    }
  }
  // Bearings need only be directions: normalise them.
  for (Eigen::Vector3d& b : s.bearings) {
    if (b.norm() > 0) b.normalize();
  }
  CheckSample(*p.method, s, source);
  return p;
}

}  // namespace linecloud
