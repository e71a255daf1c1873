#include "linecloud/geometry/plucker.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace linecloud {

bool PluckerLine::IsValid(double tolerance) const {
  if (!v.allFinite() || !w.allFinite()) return false;
  if (std::abs(v.norm() - 1.0) > tolerance) return false;
  return std::abs(v.dot(w)) <= tolerance * std::max(1.0, w.norm());
}

PluckerLine Transform(const Rigid3d& b_from_a, const PluckerLine& line) {
  const Eigen::Vector3d rv = b_from_a.rotation * line.v;
  return PluckerLine(rv, b_from_a.rotation * line.w + b_from_a.translation.cross(rv));
}

PluckerLine Transform(const Sim3d& b_from_a, const PluckerLine& line) {
  const Eigen::Vector3d rv = b_from_a.rotation * line.v;
  return PluckerLine(
      rv, b_from_a.scale * (b_from_a.rotation * line.w) + b_from_a.translation.cross(rv));
}

double LineLineDistance(const PluckerLine& a, const PluckerLine& b) {
  const Eigen::Vector3d cross = a.v.cross(b.v);
  const double sin_angle = cross.norm();
  // Reciprocal product v_a·w_b + v_b·w_a = −(distance · sin angle) up to sign.
  const double reciprocal = a.v.dot(b.w) + b.v.dot(a.w);
  if (sin_angle > 1e-12) return std::abs(reciprocal) / sin_angle;
  // Parallel: distance from a's anchor to b.
  return b.DistanceTo(a.Anchor());
}

bool ClosestPoints(const PluckerLine& a, const PluckerLine& b, Eigen::Vector3d* point_on_a,
                   Eigen::Vector3d* point_on_b) {
  const Eigen::Vector3d pa = a.Anchor();
  const Eigen::Vector3d pb = b.Anchor();
  // Minimise |pa + s va − pb − t vb|² over (s, t).
  const double c = a.v.dot(b.v);
  const double denom = 1.0 - c * c;
  const Eigen::Vector3d d = pa - pb;
  if (denom < 1e-24) {
    *point_on_a = pa;
    *point_on_b = b.ClosestPointTo(pa);
    return false;
  }
  const double da = a.v.dot(d);
  const double db = b.v.dot(d);
  const double s = (c * db - da) / denom;
  const double t = (db - c * da) / denom;
  *point_on_a = pa + s * a.v;
  *point_on_b = pb + t * b.v;
  return true;
}

bool ClipToBox(const PluckerLine& line, const Eigen::Vector3d& min, const Eigen::Vector3d& max,
               Eigen::Vector3d* from, Eigen::Vector3d* to) {
  // Points a + t v with a the anchor: t within every axis' slab.
  const Eigen::Vector3d a = line.Anchor();
  double t0 = -std::numeric_limits<double>::infinity(), t1 = -t0;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(line.v[k]) < 1e-300) {
      if (a[k] < min[k] || a[k] > max[k]) return false;
      continue;
    }
    double lo = (min[k] - a[k]) / line.v[k], hi = (max[k] - a[k]) / line.v[k];
    if (lo > hi) std::swap(lo, hi);
    t0 = std::max(t0, lo);
    t1 = std::min(t1, hi);
  }
  if (!(t0 <= t1)) return false;
  *from = a + t0 * line.v;
  *to = a + t1 * line.v;
  return true;
}

}  // namespace linecloud
