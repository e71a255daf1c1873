#include "linecloud/solvers/m_p3p_l.h"

#include "linecloud/util/check.h"

#include <cmath>

#include "linecloud/solvers/triad.h"

namespace linecloud {

int m_p3p_l(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
            std::vector<Sim3d>* out) {
  CheckMinimalSample("m_p3p_l", 3, out, points_local, points);
  out->clear();
  const Eigen::Vector3d a1 = points[1] - points[0], a2 = points[2] - points[0];
  const Eigen::Vector3d b1 = points_local[1] - points_local[0];
  const Eigen::Vector3d b2 = points_local[2] - points_local[0];
  Eigen::Matrix3d r;
  if (!TriadRotation(a1, a2, b1, b2, &r)) return 0;
  const double scale = std::sqrt((b1.squaredNorm() + b2.squaredNorm() + (b2 - b1).squaredNorm()) /
                                 (a1.squaredNorm() + a2.squaredNorm() + (a2 - a1).squaredNorm()));
  if (!(scale > 0) || !std::isfinite(scale)) return 0;
  const Eigen::Vector3d centroid = (points[0] + points[1] + points[2]) / 3.0;
  const Eigen::Vector3d centroid_local =
      (points_local[0] + points_local[1] + points_local[2]) / 3.0;
  out->emplace_back(scale, Eigen::Quaterniond(r), centroid_local - scale * (r * centroid));
  return 1;
}

}  // namespace linecloud
