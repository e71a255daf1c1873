#include "linecloud/solvers/m_p3l_lu.h"

#include <cmath>

#include <Eigen/LU>

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p3l_lu(std::span<const PluckerLine> lines,
             std::span<const Eigen::Vector3d> points_local, std::vector<Sim3d>* out) {
  out->clear();
  // Unknowns x = (p, q, r, t') with p = s' c, q = s' s, r = s':
  //   uᵀ (p A(X̃) + q B(X̃) + r D(X̃) + t') = uᵀ anchor.
  Eigen::Matrix<double, 6, 6> m;
  Eigen::Matrix<double, 6, 1> b;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d& x = points_local[i];
    if (!x.allFinite() || !lines[i].v.allFinite() || !lines[i].w.allFinite() ||
        !(lines[i].v.squaredNorm() > 0)) {
      return 0;
    }
    Eigen::Vector3d u[2];
    upright::OrthogonalBasis(lines[i].v, &u[0], &u[1]);
    const Eigen::Vector3d anchor = lines[i].Anchor();
    for (int k = 0; k < 2; ++k) {
      const int row = 2 * i + k;
      m(row, 0) = u[k].dot(upright::A(x));
      m(row, 1) = u[k].dot(upright::B(x));
      m(row, 2) = u[k].dot(upright::D(x));
      m.block<1, 3>(row, 3) = u[k].transpose();
      b[row] = u[k].dot(anchor);
    }
  }
  const Eigen::PartialPivLU<Eigen::Matrix<double, 6, 6>> lu(m);
  // Reject (near-)singular systems: degenerate configurations.
  const double det = lu.determinant();
  const double norm2 = m.squaredNorm();
  if (!(std::abs(det) > 1e-14 * norm2 * norm2 * norm2) || !std::isfinite(det)) return 0;
  const Eigen::Matrix<double, 6, 1> x = lu.solve(b);
  const double scale = std::sqrt(x[0] * x[0] + x[1] * x[1]);
  if (!(scale > 0) || !(x[2] > 0) || !x.allFinite()) return 0;
  const Sim3d world_from_local(scale, upright::RotationY(x[0], x[1]), x.tail<3>());
  out->push_back(world_from_local.Inverse());
  return 1;
}

}  // namespace linecloud
