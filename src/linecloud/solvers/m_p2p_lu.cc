#include "linecloud/solvers/m_p2p_lu.h"

#include "linecloud/util/check.h"

#include <cmath>

#include "linecloud/solvers/m_p2p_lus.h"

namespace linecloud {

int m_p2p_lu(std::span<const Eigen::Vector3d> points_local, std::span<const Eigen::Vector3d> points,
             std::vector<Sim3d>* out) {
  CheckMinimalSample("m_p2p_lu", 2, out, points_local, points);
  out->clear();
  const double scale = std::sqrt((points_local[1] - points_local[0]).squaredNorm() /
                                 (points[1] - points[0]).squaredNorm());
  if (!(scale > 0) || !std::isfinite(scale)) return 0;
  Eigen::Quaterniond rotation;
  Eigen::Vector3d translation;
  if (!UprightTwoPointAlignment(points_local, points, scale, &rotation, &translation)) return 0;
  out->emplace_back(scale, rotation, translation);
  return 1;
}

}  // namespace linecloud
