#include "linecloud/solvers/m_p2p_u.h"

#include <Eigen/LU>

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p2p_u(std::span<const Eigen::Vector3d> origins,
            std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  out->clear();
  // Rows k: u_kᵀ (c A_i + s B_i + D_i + t − o_i) = 0.
  Eigen::Matrix<double, 4, 3> bt;
  Eigen::Vector4d alpha, beta, gamma;
  for (int i = 0; i < 2; ++i) {
    if (!(directions[i].squaredNorm() > 0) || !directions[i].allFinite() ||
        !points[i].allFinite() || !origins[i].allFinite()) {
      return 0;
    }
    Eigen::Vector3d u[2];
    upright::OrthogonalBasis(directions[i], &u[0], &u[1]);
    for (int k = 0; k < 2; ++k) {
      const int row = 2 * i + k;
      bt.row(row) = u[k].transpose();
      alpha[row] = u[k].dot(upright::A(points[i]));
      beta[row] = u[k].dot(upright::B(points[i]));
      gamma[row] = u[k].dot(upright::D(points[i]) - origins[i]);
    }
  }
  // Left null vector of bt: signed 3x3 minors.
  Eigen::Vector4d n;
  for (int j = 0; j < 4; ++j) {
    Eigen::Matrix3d minor;
    for (int r = 0, m = 0; r < 4; ++r) {
      if (r != j) minor.row(m++) = bt.row(r);
    }
    n[j] = (j % 2 ? -1.0 : 1.0) * minor.determinant();
  }
  const double scale = n.norm();
  if (!(scale > 1e-12)) return 0;  // parallel rays: t is not determined
  n /= scale;
  double cs[2][2];
  const int count = upright::IntersectLineUnitCircle(n.dot(alpha), n.dot(beta),
                                                     n.dot(gamma), cs);
  const Eigen::Matrix3d normal = bt.transpose() * bt;
  const Eigen::Matrix<double, 3, 4> pinv = normal.inverse() * bt.transpose();
  for (int k = 0; k < count; ++k) {
    const double c = cs[k][0], s = cs[k][1];
    const Eigen::Vector3d t = -pinv * (c * alpha + s * beta + gamma);
    if (!t.allFinite()) continue;
    out->emplace_back(upright::RotationY(c, s), t);
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
