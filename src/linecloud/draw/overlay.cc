#include "linecloud/draw/overlay.h"

#include <cairo.h>

#include <algorithm>
#include <cstring>
#include <memory>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

cairo_status_t AppendPng(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

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

void WriteLocalizationOverlay(const std::string& path, const GreyImage& photo, const Query& query,
                              const LocalizeResult& result, const LocalizationMap& map) {
  if (query.cameras.size() != 1) Fail("{}: an overlay draws one photo's query", path);
  const Camera& camera = query.cameras[0];
  std::unique_ptr<cairo_surface_t, void (*)(cairo_surface_t*)> surface(
      cairo_image_surface_create(CAIRO_FORMAT_RGB24, photo.width, photo.height),
      cairo_surface_destroy);
  cairo_surface_flush(surface.get());
  unsigned char* pixels = cairo_image_surface_get_data(surface.get());
  const int stride = cairo_image_surface_get_stride(surface.get());
  if (!pixels) Fail("{}: cannot allocate a {}x{} picture", path, photo.width, photo.height);
  for (int y = 0; y < photo.height; ++y) {
    uint32_t* row = reinterpret_cast<uint32_t*>(pixels + static_cast<size_t>(y) * stride);
    for (int x = 0; x < photo.width; ++x) {
      const uint32_t g = photo.at(x, y) / 2 + 40;  // dimmed so that the marks stand out
      row[x] = (g << 16) | (g << 8) | g;
    }
  }
  cairo_surface_mark_dirty(surface.get());
  std::unique_ptr<cairo_t, void (*)(cairo_t*)> cr(cairo_create(surface.get()), cairo_destroy);
  cairo_set_line_width(cr.get(), std::max(1.0, photo.width / 1000.0));
  std::vector<char> inlier(query.observations.size(), 0);
  for (const int i : result.inliers) inlier[i] = 1;
  const Sim3d& cam_from_world = result.query_from_world;
  const double r = std::max(2.0, photo.width / 500.0);
  for (size_t i = 0; i < query.observations.size(); ++i) {
    const QueryObservation& o = query.observations[i];
    if (inlier[i] && result.has_pose) {
      cairo_set_source_rgb(cr.get(), 1.0, 0.85, 0.1);  // where the pose puts the map feature
      if (const LineMap* lines = std::get_if<LineMap>(&map)) {
        const auto it = lines->lines.find(o.line_id.value_or(o.id));
        Eigen::Vector2d c, d;
        if (it != lines->lines.end() &&
            ProjectedLineNear(camera, cam_from_world, it->second, o.xy, &c, &d)) {
          const double half = 6 * r;
          cairo_move_to(cr.get(), c.x() - half * d.x(), c.y() - half * d.y());
          cairo_line_to(cr.get(), c.x() + half * d.x(), c.y() + half * d.y());
          cairo_stroke(cr.get());
        }
      } else {
        const auto& points = std::get<PointMap>(map).points;
        const auto it = points.find(o.id);
        if (it != points.end()) {
          const Eigen::Vector3d x = cam_from_world * it->second;
          if (x.z() > 0) {
            const Eigen::Vector2d p = camera.ImgFromCam(x);
            cairo_move_to(cr.get(), o.xy.x(), o.xy.y());
            cairo_line_to(cr.get(), p.x(), p.y());
            cairo_stroke(cr.get());
          }
        }
      }
    }
    if (inlier[i]) {
      cairo_set_source_rgb(cr.get(), 0.1, 0.9, 0.2);
    } else {
      cairo_set_source_rgb(cr.get(), 0.95, 0.15, 0.1);
    }
    // The keypoint (COLMAP convention: pixel centres at +0.5, as cairo's).
    cairo_arc(cr.get(), o.xy.x(), o.xy.y(), r, 0, 2 * 3.141592653589793);
    cairo_stroke(cr.get());
  }
  cairo_surface_flush(surface.get());
  std::string png;
  const cairo_status_t status = cairo_surface_write_to_png_stream(surface.get(), AppendPng, &png);
  if (status != CAIRO_STATUS_SUCCESS) {
    Fail("{}: cannot encode the PNG ({})", path, cairo_status_to_string(status));
  }
  WriteFileAtomically(path, [&](std::ostream& os) { os << png; });
}

}  // namespace linecloud
