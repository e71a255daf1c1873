// The audit's picture: what leaks, at a glance. The secret points (left) and
// the points an attacker recovers from the line cloud (right), drawn from the
// same two viewpoints (rows), the recovered ones coloured by their error.
#pragma once

#include <array>
#include <span>
#include <string>

#include <Eigen/Core>

namespace linecloud {

struct AuditFigureText {
  std::string title;     // first line of the picture
  std::string subtitle;  // e.g. the recovery figures
};

// The error colour of the figure and of recovered.ply (RGB in [0, 1]):
// sky blue (error 0) → yellow (1 % of `diagonal`) → vermilion (≥ 2 %), a
// colour-blind-safe scale (Okabe and Ito).
std::array<double, 3> ErrorColour(double error, double diagonal);

// Views: along the secret points' least-spread principal axis ("front") and
// along the middle one ("top"), both drawn in the plane of the two others.
// Colours: sky blue (error 0) → yellow (1 % of `diagonal`) → vermilion (≥ 2 %).
// Throws Error naming `path` when it cannot be written.
// Written mode 0600 (it shows the secret points).
void WriteAuditFigure(const std::string& path, std::span<const Eigen::Vector3d> secret,
                      std::span<const Eigen::Vector3d> recovered, std::span<const double> errors,
                      double diagonal, const AuditFigureText& text);

}  // namespace linecloud
