#include "linecloud/localize/overlay_marks.h"

#include <algorithm>
#include <variant>

#include "linecloud/geometry/plucker.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

// The map line of an observation as drawn: the point of the line closest to
// the keypoint's viewing ray, and a direction along the line's projection.
bool ProjectedLineNear(const Camera& camera, const Sim3d& cam_from_world, const PluckerLine& world,
                       const Eigen::Vector2d& xy, Eigen::Vector2d* centre,
                       Eigen::Vector2d* direction) {
  const PluckerLine line = Transform(cam_from_world, world);
  const PluckerLine ray = PluckerLine::FromPointAndDirection(Eigen::Vector3d::Zero(),
                                                             camera.CamFromImg(xy).normalized());
  Eigen::Vector3d on_line, on_ray;
  if (!ClosestPoints(line, ray, &on_line, &on_ray) || on_line.z() <= 1e-9) return false;
  const double step = 1e-3 * on_line.z();
  const Eigen::Vector3d ahead = on_line + step * line.v;
  if (ahead.z() <= 1e-9) return false;
  *centre = camera.ImgFromCam(on_line);
  const Eigen::Vector2d d = camera.ImgFromCam(ahead) - *centre;
  if (!(d.norm() > 0) || !centre->allFinite()) return false;
  *direction = d.normalized();
  return true;
}

}  // namespace

double OverlaySegmentHalfLength(int width) { return 6 * std::max(2.0, width / 500.0); }

std::vector<OverlayMark> OverlayMarks(const Query& query, const LocalizeResult& result,
                                      const LocalizationMap& map, double half_length) {
  if (query.cameras.size() != 1) Fail("overlay: a picture shows one photo's query");
  const Camera& camera = query.cameras[0];
  std::vector<OverlayMark> marks(query.observations.size());
  for (size_t i = 0; i < marks.size(); ++i) marks[i].keypoint = query.observations[i].xy;
  for (const int i : result.inliers) {
    if (i < 0 || static_cast<size_t>(i) >= marks.size()) Fail("overlay: inlier {} out of range", i);
    marks[i].inlier = true;
  }
  if (!result.has_pose) return marks;
  const Sim3d& cam_from_world = result.query_from_world;
  for (size_t i = 0; i < marks.size(); ++i) {
    if (!marks[i].inlier) continue;
    const QueryObservation& o = query.observations[i];
    if (const LineMap* lines = std::get_if<LineMap>(&map)) {
      const auto it = lines->lines.find(o.line_id.value_or(o.id));
      Eigen::Vector2d c, d;
      if (it != lines->lines.end() &&
          ProjectedLineNear(camera, cam_from_world, it->second, o.xy, &c, &d)) {
        marks[i].feature = std::pair(c - half_length * d, c + half_length * d);
      }
    } else {
      const auto& points = std::get<PointMap>(map).points;
      const auto it = points.find(o.id);
      if (it == points.end()) continue;
      const Eigen::Vector3d x = cam_from_world * it->second;
      if (x.z() > 0) marks[i].feature = std::pair(o.xy, camera.ImgFromCam(x));
    }
  }
  return marks;
}

}  // namespace linecloud
