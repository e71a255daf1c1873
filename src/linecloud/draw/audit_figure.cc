#include "linecloud/draw/audit_figure.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include <Eigen/Eigenvalues>
#include <cairo.h>

#include "linecloud/util/error.h"
#include "linecloud/util/file.h"

namespace linecloud {
namespace {

constexpr int kPanelW = 640, kPanelH = 480, kMargin = 16, kHeader = 70, kLabel = 24;

struct View {
  Eigen::Vector3d u, v;  // image axes
  const char* name;
};

double Percentile(std::vector<double> v, double q) {
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * (v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

std::array<double, 3> ErrorColour(double error, double diagonal) {
  const double x = diagonal > 0 ? std::clamp(error / (0.02 * diagonal), 0.0, 1.0) : 1.0;
  // Okabe and Ito's colour-blind-safe sky blue (exact) → yellow (x = 0.5) → vermilion: apart
  // for every kind of colour vision (blue against orange), readable on black and white.
  const std::array<double, 3> sky = {0.337, 0.706, 0.914}, yellow = {0.941, 0.894, 0.259},
                              vermilion = {0.835, 0.369, 0.0};
  const auto mix = [](const std::array<double, 3>& a, const std::array<double, 3>& b, double t) {
    return std::array<double, 3>{a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1]),
                                 a[2] + t * (b[2] - a[2])};
  };
  return x < 0.5 ? mix(sky, yellow, 2 * x) : mix(yellow, vermilion, 2 * x - 1);
}

void WriteAuditFigure(const std::string& path, std::span<const Eigen::Vector3d> secret,
                      std::span<const Eigen::Vector3d> recovered, std::span<const double> errors,
                      double diagonal, const AuditFigureText& text) {
  if (secret.empty() || recovered.size() != secret.size() || errors.size() != secret.size()) {
    Fail("{}: nothing to draw ({} secret, {} recovered points)", path, secret.size(),
         recovered.size());
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : secret) mean += p;
  mean /= static_cast<double>(secret.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& p : secret) cov += (p - mean) * (p - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);  // ascending eigenvalues
  const Eigen::Vector3d a0 = eig.eigenvectors().col(0), a1 = eig.eigenvectors().col(1),
                        a2 = eig.eigenvectors().col(2);
  const View views[2] = {{a2, a1, "front (along the least-spread axis)"},
                         {a2, a0, "top (along the middle axis)"}};

  const int width = 2 * kPanelW + 3 * kMargin;
  const int height = kHeader + 2 * (kPanelH + kLabel) + 3 * kMargin;
  cairo_surface_t* surface = cairo_image_surface_create(CAIRO_FORMAT_RGB24, width, height);
  cairo_t* cr = cairo_create(surface);
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_BOLD);
  cairo_set_font_size(cr, 18);
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_move_to(cr, kMargin, 28);
  cairo_show_text(cr, text.title.c_str());
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, 14);
  cairo_move_to(cr, kMargin, 54);
  cairo_show_text(cr, text.subtitle.c_str());

  const double dot = std::clamp(3.0 * std::sqrt(20000.0 / secret.size()), 1.0, 4.0);
  for (int row = 0; row < 2; ++row) {
    const View& view = views[row];
    std::vector<double> us, vs;
    for (const auto& p : secret)
      us.push_back(view.u.dot(p - mean)), vs.push_back(view.v.dot(p - mean));
    const double u0 = Percentile(us, 0.005), u1 = Percentile(us, 0.995);
    const double v0 = Percentile(vs, 0.005), v1 = Percentile(vs, 0.995);
    const double scale = std::min((kPanelW - 20) / std::max(u1 - u0, 1e-12),
                                  (kPanelH - 20) / std::max(v1 - v0, 1e-12));
    for (int col = 0; col < 2; ++col) {
      const double x0 = kMargin + col * (kPanelW + kMargin);
      const double y0 = kHeader + kMargin + row * (kPanelH + kLabel + kMargin);
      cairo_set_source_rgb(cr, 0, 0, 0);
      cairo_move_to(cr, x0, y0 + 16);
      cairo_show_text(
          cr, (std::string(col == 0 ? "secret points, " : "recovered by the attack, ") + view.name)
                  .c_str());
      const double py = y0 + kLabel;
      cairo_set_source_rgb(cr, 0.97, 0.97, 0.97);
      cairo_rectangle(cr, x0, py, kPanelW, kPanelH);
      cairo_fill(cr);
      cairo_save(cr);
      cairo_rectangle(cr, x0, py, kPanelW, kPanelH);
      cairo_clip(cr);
      const double cu = 0.5 * (u0 + u1), cv = 0.5 * (v0 + v1);
      for (size_t i = 0; i < secret.size(); ++i) {
        const Eigen::Vector3d p = (col == 0 ? secret[i] : recovered[i]) - mean;
        const double x = x0 + kPanelW / 2.0 + scale * (view.u.dot(p) - cu);
        const double y = py + kPanelH / 2.0 - scale * (view.v.dot(p) - cv);
        if (col == 0) {
          cairo_set_source_rgb(cr, 0.25, 0.25, 0.3);
        } else {
          const auto c = ErrorColour(errors[i], diagonal);
          cairo_set_source_rgb(cr, c[0], c[1], c[2]);
        }
        cairo_rectangle(cr, x - dot / 2, y - dot / 2, dot, dot);
        cairo_fill(cr);
      }
      cairo_restore(cr);
    }
  }
  cairo_destroy(cr);
  const cairo_status_t status = cairo_surface_status(surface);
  std::string png;
  if (status == CAIRO_STATUS_SUCCESS) {
    cairo_surface_write_to_png_stream(
        surface,
        [](void* closure, const unsigned char* data, unsigned int length) {
          static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
          return CAIRO_STATUS_SUCCESS;
        },
        &png);
  }
  cairo_surface_destroy(surface);
  if (png.empty()) Fail("{}: cannot render the audit figure", path);
  // The recovered points are the secret the map protects: the owner's only.
  WriteFileAtomically(
      path, [&](std::ostream& out) { out.write(png.data(), png.size()); }, 0600);
}

}  // namespace linecloud
