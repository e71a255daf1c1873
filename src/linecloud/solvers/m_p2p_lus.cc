#include "linecloud/solvers/m_p2p_lus.h"

#include "linecloud/util/check.h"

#include <cmath>

#include "linecloud/solvers/upright.h"

namespace linecloud {

bool UprightTwoPointAlignment(std::span<const Eigen::Vector3d> points_local,
                              std::span<const Eigen::Vector3d> points, double scale,
                              Eigen::Quaterniond* rotation, Eigen::Vector3d* translation) {
  const Eigen::Vector3d d = points[1] - points[0];
  const Eigen::Vector3d e = points_local[1] - points_local[0];
  // e^{iθ} = (e_z + i e_x) / (d_z + i d_x), normalised.
  const double re = e.z() * d.z() + e.x() * d.x();
  const double im = e.x() * d.z() - e.z() * d.x();
  const double norm2 = re * re + im * im;
  const double size = d.squaredNorm() + e.squaredNorm();
  if (!(norm2 > 1e-24 * size * size) || !std::isfinite(norm2)) {
    return false;
  }
  *rotation = upright::RotationY(re, im);
  // R_y(θ) m = (c m_x + s m_z, m_y, −s m_x + c m_z), (c, s) from the half angle.
  const double w = rotation->w(), y = rotation->y();
  const double c = w * w - y * y, sn = 2 * w * y;
  const double h = 0.5 * scale;
  const double mx = h * (points[0].x() + points[1].x()), my = h * (points[0].y() + points[1].y()),
               mz = h * (points[0].z() + points[1].z());
  *translation =
      Eigen::Vector3d(0.5 * (points_local[0].x() + points_local[1].x()) - (c * mx + sn * mz),
                      0.5 * (points_local[0].y() + points_local[1].y()) - my,
                      0.5 * (points_local[0].z() + points_local[1].z()) - (c * mz - sn * mx));
  return translation->allFinite();
}

int m_p2p_lus(std::span<const Eigen::Vector3d> points_local,
              std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p2p_lus", 2, out, points_local, points);
  out->clear();
  Eigen::Quaterniond rotation;
  Eigen::Vector3d translation;
  if (!UprightTwoPointAlignment(points_local, points, 1.0, &rotation, &translation)) return 0;
  out->emplace_back(rotation, translation);
  return 1;
}

}  // namespace linecloud
