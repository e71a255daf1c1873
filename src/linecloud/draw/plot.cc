#include "linecloud/draw/plot.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <cairo.h>
#include <fmt/core.h>

#include "linecloud/util/error.h"

namespace linecloud {
namespace {

struct Rgb {
  double r, g, b;
};
constexpr Rgb kPalette[] = {{0.12, 0.47, 0.71}, {1.00, 0.50, 0.05}, {0.17, 0.63, 0.17},
                            {0.84, 0.15, 0.16}, {0.58, 0.40, 0.74}, {0.55, 0.34, 0.29},
                            {0.89, 0.47, 0.76}, {0.50, 0.50, 0.50}, {0.74, 0.74, 0.13},
                            {0.09, 0.75, 0.81}};

// 1, 2, 5 × 10^k steps giving about `target` ticks.
double NiceStep(double span, int target) {
  const double raw = span / target;
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * p >= raw) return m * p;
  }
  return 10 * p;
}

std::string TickLabel(double v, double step) {
  if (std::abs(v) < 1e-12 * step) v = 0;
  const int decimals = std::max(0, -static_cast<int>(std::floor(std::log10(step) + 1e-9)));
  return fmt::format("{:.{}f}", v, decimals);
}

bool Valid(const PlotOptions& o, double x, double y) {
  return std::isfinite(x) && std::isfinite(y) && !(o.log_x && x <= 0) && !(o.log_y && y <= 0);
}

}  // namespace

void WriteLinePlot(const std::string& path, const PlotOptions& o,
                   const std::vector<PlotSeries>& series) {
  double x0 = std::numeric_limits<double>::infinity(), x1 = -x0, y0 = x0, y1 = -x0;
  for (const PlotSeries& s : series) {
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!Valid(o, s.x[i], s.y[i])) continue;
      const double x = o.log_x ? std::log10(s.x[i]) : s.x[i];
      x0 = std::min(x0, x);
      x1 = std::max(x1, x);
      const double y = o.log_y ? std::log10(s.y[i]) : s.y[i];
      y0 = std::min(y0, y);
      y1 = std::max(y1, y);
    }
  }
  if (o.x_max > o.x_min) {
    x0 = o.log_x ? std::log10(o.x_min) : o.x_min;
    x1 = o.log_x ? std::log10(o.x_max) : o.x_max;
  }
  if (o.y_max > o.y_min) {
    y0 = o.log_y ? std::log10(o.y_min) : o.y_min;
    y1 = o.log_y ? std::log10(o.y_max) : o.y_max;
  }
  if (!std::isfinite(x0)) x0 = 0, x1 = 1;
  if (!std::isfinite(y0)) y0 = 0, y1 = 1;
  if (x1 <= x0) x1 = x0 + 1;
  if (y1 <= y0) y1 = y0 + 1;
  if (o.log_x) {
    x0 = std::floor(x0);
    x1 = std::ceil(x1);
    if (x1 <= x0) x1 = x0 + 1;
  }
  if (o.log_y) {
    y0 = std::floor(y0);
    y1 = std::ceil(y1);
    if (y1 <= y0) y1 = y0 + 1;
  }

  cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_ARGB32, o.width, o.height);
  cairo_t* cr = cairo_create(surface);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  const double left = 90, right = 230, top = 50, bottom = 70;
  const double pw = o.width - left - right, ph = o.height - top - bottom;
  auto px = [&](double x) {
    const double v = o.log_x ? std::log10(x) : x;
    return left + (std::clamp(v, x0, x1) - x0) / (x1 - x0) * pw;
  };
  auto py = [&](double y) {
    const double v = o.log_y ? std::log10(y) : y;
    return top + ph - (std::clamp(v, y0, y1) - y0) / (y1 - y0) * ph;
  };
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  auto text = [&](double x, double y, const std::string& s, double size, double align_x,
                  double align_y) {
    cairo_set_font_size(cr, size);
    cairo_text_extents_t e;
    cairo_text_extents(cr, s.c_str(), &e);
    cairo_move_to(cr, x - align_x * e.width - e.x_bearing, y - align_y * e.height - e.y_bearing);
    cairo_show_text(cr, s.c_str());
  };

  // Grid and ticks.
  cairo_set_line_width(cr, 1);
  const double xs = o.log_x ? 1.0 : NiceStep(x1 - x0, 8);
  for (double x = std::ceil(x0 / xs) * xs; x <= x1 + 1e-9 * xs; x += xs) {
    const double xv = o.log_x ? std::pow(10.0, x) : x;
    cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
    cairo_move_to(cr, px(xv), top);
    cairo_line_to(cr, px(xv), top + ph);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(px(xv), top + ph + 8, o.log_x ? fmt::format("{:g}", xv) : TickLabel(x, xs), 13, 0.5, 0);
  }
  const double ys = o.log_y ? 1.0 : NiceStep(y1 - y0, 6);
  for (double y = std::ceil(y0 / ys) * ys; y <= y1 + 1e-9 * ys; y += ys) {
    const double yv = o.log_y ? std::pow(10.0, y) : y;
    cairo_set_source_rgb(cr, 0.9, 0.9, 0.9);
    cairo_move_to(cr, left, py(yv));
    cairo_line_to(cr, left + pw, py(yv));
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(left - 8, py(yv), o.log_y ? fmt::format("{:g}", yv) : TickLabel(y, ys), 13, 1, 0.5);
  }
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_rectangle(cr, left, top, pw, ph);
  cairo_stroke(cr);
  text(left + pw / 2, 15, o.title, 18, 0.5, 0);
  text(left + pw / 2, o.height - 25, o.x_label, 15, 0.5, 0);
  cairo_save(cr);
  cairo_translate(cr, 22, top + ph / 2);
  cairo_rotate(cr, -M_PI / 2);
  text(0, 0, o.y_label, 15, 0.5, 0.5);
  cairo_restore(cr);

  // Curves and legend.
  cairo_rectangle(cr, left, top, pw, ph);
  cairo_save(cr);
  cairo_clip(cr);
  const double dash[] = {7, 4};
  for (const PlotSeries& s : series) {
    const Rgb c = kPalette[s.color % std::size(kPalette)];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 2);
    cairo_set_dash(cr, dash, s.dashed ? 2 : 0, 0);
    bool pen = false;
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!Valid(o, s.x[i], s.y[i])) {
        pen = false;
        continue;
      }
      if (pen)
        cairo_line_to(cr, px(s.x[i]), py(s.y[i]));
      else
        cairo_move_to(cr, px(s.x[i]), py(s.y[i]));
      pen = true;
    }
    cairo_stroke(cr);
    cairo_set_dash(cr, dash, 0, 0);
    for (size_t i = 0; i < std::min(s.x.size(), s.y.size()); ++i) {
      if (!Valid(o, s.x[i], s.y[i])) continue;
      if (s.markers) {
        cairo_set_source_rgb(cr, c.r, c.g, c.b);
        cairo_arc(cr, px(s.x[i]), py(s.y[i]), 4.5, 0, 2 * M_PI);
        cairo_fill(cr);
      }
      if (i < s.labels.size() && !s.labels[i].empty()) {
        cairo_set_source_rgb(cr, 0.2, 0.2, 0.2);
        text(px(s.x[i]) + 7, py(s.y[i]) - 4, s.labels[i], 11, 0, 1);
      }
    }
  }
  cairo_restore(cr);
  double ly = top + 10;
  for (const PlotSeries& s : series) {
    const Rgb c = kPalette[s.color % std::size(kPalette)];
    cairo_set_source_rgb(cr, c.r, c.g, c.b);
    cairo_set_line_width(cr, 2);
    cairo_set_dash(cr, dash, s.dashed ? 2 : 0, 0);
    cairo_move_to(cr, left + pw + 15, ly);
    cairo_line_to(cr, left + pw + 50, ly);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0, 0, 0);
    text(left + pw + 58, ly, s.name, 13, 0, 0.5);
    ly += 20;
  }
  cairo_destroy(cr);
  const cairo_status_t status = cairo_surface_write_to_png(surface, path.c_str());
  cairo_surface_destroy(surface);
  if (status != CAIRO_STATUS_SUCCESS)
    Fail("{}: cannot write PNG ({})", path, cairo_status_to_string(status));
}

}  // namespace linecloud
