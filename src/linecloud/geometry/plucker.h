// Plücker lines L = (v, w): |v| = 1 and w = X × v for any point X on the line.
// The point of L closest to the origin is v × w; every point is v × w + α v.
// A line has no orientation: (v, w) and (−v, −w) are the same line.
#pragma once

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

struct PluckerLine {
  Eigen::Vector3d v = Eigen::Vector3d::UnitX();  // unit direction
  Eigen::Vector3d w = Eigen::Vector3d::Zero();   // moment, w = X × v

  PluckerLine() = default;
  PluckerLine(const Eigen::Vector3d& direction, const Eigen::Vector3d& moment)
      : v(direction), w(moment) {}

  // The line through `point` with direction `direction` (normalised here).
  static PluckerLine FromPointAndDirection(const Eigen::Vector3d& point,
                                           const Eigen::Vector3d& direction) {
    const Eigen::Vector3d v = direction.normalized();
    return PluckerLine(v, point.cross(v));
  }

  // The point of the line closest to the origin.
  Eigen::Vector3d Anchor() const { return v.cross(w); }

  Eigen::Vector3d PointAt(double alpha) const { return Anchor() + alpha * v; }

  // Euclidean distance from x to the line: |x × v − w|.
  double DistanceTo(const Eigen::Vector3d& x) const { return (x.cross(v) - w).norm(); }

  // The point of the line closest to x.
  Eigen::Vector3d ClosestPointTo(const Eigen::Vector3d& x) const {
    const Eigen::Vector3d anchor = Anchor();
    return anchor + v.dot(x - anchor) * v;
  }

  // True when the representation is valid: finite, unit v, w ⟂ v.
  bool IsValid(double tolerance = 1e-9) const;
};

// Moves a line from frame a to frame b: v_b = R v_a, w_b = R w_a + t × R v_a.
PluckerLine Transform(const Rigid3d& b_from_a, const PluckerLine& line);

// Similarity: points map as x_b = s R x_a + t, so v_b = R v_a and
// w_b = s R w_a + t × R v_a.
PluckerLine Transform(const Sim3d& b_from_a, const PluckerLine& line);

// Shortest distance between two lines (0 when they meet).
double LineLineDistance(const PluckerLine& a, const PluckerLine& b);

// The pair of mutually closest points (on a, on b). For parallel lines one
// valid pair is returned (the one through a's anchor). Returns false when the
// lines are parallel.
bool ClosestPoints(const PluckerLine& a, const PluckerLine& b, Eigen::Vector3d* point_on_a,
                   Eigen::Vector3d* point_on_b);

// The segment of `line` inside the axis-aligned box [min, max] (slab
// clipping); false when the line misses the box.
bool ClipToBox(const PluckerLine& line, const Eigen::Vector3d& min, const Eigen::Vector3d& max,
               Eigen::Vector3d* from, Eigen::Vector3d* to);

}  // namespace linecloud
