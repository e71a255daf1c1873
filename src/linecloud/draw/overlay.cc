#include "linecloud/draw/overlay.h"

#include <cairo.h>

#include <algorithm>
#include <cstring>
#include <memory>

#include "linecloud/localize/overlay_marks.h"
#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

cairo_status_t AppendPng(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

void WriteLocalizationOverlay(const std::string& path, const GreyImage& photo, const Query& query,
                              const LocalizeResult& result, const LocalizationMap& map) {
  if (query.cameras.size() != 1) Fail("{}: an overlay draws one photo's query", path);
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
  const double r = std::max(2.0, photo.width / 500.0);
  for (const OverlayMark& m :
       OverlayMarks(query, result, map, OverlaySegmentHalfLength(photo.width))) {
    if (m.feature) {
      cairo_set_source_rgb(cr.get(), 0.941, 0.894, 0.259);  // yellow: where the pose puts it
      cairo_move_to(cr.get(), m.feature->first.x(), m.feature->first.y());
      cairo_line_to(cr.get(), m.feature->second.x(), m.feature->second.y());
      cairo_stroke(cr.get());
    }
    if (m.inlier) {
      cairo_set_source_rgb(cr.get(), 0.337, 0.706, 0.914);  // sky blue
    } else {
      cairo_set_source_rgb(cr.get(), 0.835, 0.369, 0.0);  // vermilion
    }
    // The keypoint (COLMAP convention: pixel centres at +0.5, as cairo's).
    cairo_arc(cr.get(), m.keypoint.x(), m.keypoint.y(), r, 0, 2 * 3.141592653589793);
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
