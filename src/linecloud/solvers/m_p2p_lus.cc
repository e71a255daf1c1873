#include "linecloud/solvers/m_p2p_lus.h"

#include <cmath>

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p2p_lus(std::span<const Eigen::Vector3d> points_local,
              std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  out->clear();
  const Eigen::Vector3d d = points[1] - points[0];
  const Eigen::Vector3d e = points_local[1] - points_local[0];
  // e^{iθ} = (e_z + i e_x) / (d_z + i d_x), normalised.
  const double re = e.z() * d.z() + e.x() * d.x();
  const double im = e.x() * d.z() - e.z() * d.x();
  const double norm2 = re * re + im * im;
  if (!(norm2 > 1e-24 * (d.squaredNorm() + e.squaredNorm()) * (d.squaredNorm() + e.squaredNorm())) ||
      !std::isfinite(norm2)) {
    return 0;
  }
  const Eigen::Quaterniond q = upright::RotationY(re, im);
  const Eigen::Vector3d t = 0.5 * (points_local[0] + points_local[1]) -
                            q * (0.5 * (points[0] + points[1]));
  out->emplace_back(q, t);
  return 1;
}

}  // namespace linecloud
