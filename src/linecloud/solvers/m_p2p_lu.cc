#include "linecloud/solvers/m_p2p_lu.h"

#include <array>
#include <cmath>

#include "linecloud/solvers/m_p2p_lus.h"

namespace linecloud {

int m_p2p_lu(std::span<const Eigen::Vector3d> points_local,
             std::span<const Eigen::Vector3d> points, std::vector<Sim3d>* out) {
  out->clear();
  const double scale =
      (points_local[1] - points_local[0]).norm() / (points[1] - points[0]).norm();
  if (!(scale > 0) || !std::isfinite(scale)) return 0;
  // The rotation does not depend on the scale: solve the rigid case on the
  // scaled map points, then fold the scale back in.
  const std::array<Eigen::Vector3d, 2> scaled = {scale * points[0], scale * points[1]};
  Rigid3d rigid;
  if (!m_p2p_lus(points_local, scaled, &rigid)) return 0;
  out->emplace_back(scale, rigid.rotation, rigid.translation);
  return 1;
}

}  // namespace linecloud
