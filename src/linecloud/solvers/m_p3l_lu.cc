#include "linecloud/solvers/m_p3l_lu.h"

#include "linecloud/util/check.h"

#include <cmath>

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p3l_lu(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
             std::vector<Sim3d>* out) {
  CheckMinimalSample("m_p3l_lu", 3, out, lines, points_local);
  out->clear();
  Eigen::Vector3d anchor[3];
  for (int i = 0; i < 3; ++i) {
    const double v2 = lines[i].v.squaredNorm();
    if (!points_local[i].allFinite() || !lines[i].v.allFinite() || !lines[i].w.allFinite() ||
        !(v2 > 0)) {
      return 0;
    }
    anchor[i] = lines[i].v.cross(lines[i].w) / v2;
  }
  // With y = (p, q, r) = (s' c, s' s, s') and K(X) = [A(X) B(X) D(X)], the
  // constraints read K(X̃_i) y + t' = a_i + λ_i v_i. Differences to line 0
  // remove t': K(Δ_i) y − Δa_i = λ_i v_i − λ_0 v_0 (i = 1, 2), and
  //   · along n_i = v_i × v_0 both λ vanish: n_iᵀ K(Δ_i) y = n_iᵀ Δa_i;
  //   · along g_i = w_i / (v_0·w_i), w_i = v_i × n_i ⟂ v_i, only −λ_0 is
  //     left; equating the two values of λ_0 gives the third equation.
  // A 3 × 3 system (Cramer's rule), then λ_0 and t'.
  const Eigen::Vector3d& v0 = lines[0].v;
  Eigen::Matrix3d k_delta[2];
  Eigen::Vector3d delta_anchor[2], n[2], g[2];
  for (int i = 0; i < 2; ++i) {
    const Eigen::Vector3d delta = points_local[i + 1] - points_local[0];
    k_delta[i] << upright::A(delta), upright::B(delta), upright::D(delta);
    delta_anchor[i] = anchor[i + 1] - anchor[0];
    const Eigen::Vector3d& vi = lines[i + 1].v;
    n[i] = vi.cross(v0);
    const double n2 = n[i].squaredNorm();
    // Line i parallel to line 0: their difference does not fix λ.
    if (!(n2 > 1e-20 * vi.squaredNorm() * v0.squaredNorm())) return 0;
    g[i] = -vi.cross(n[i]) / n2;  // v_0·(v_i × n_i) = −|n_i|²
  }
  Eigen::Matrix3d m;
  Eigen::Vector3d b;
  for (int i = 0; i < 2; ++i) {
    m.row(i) = n[i].transpose() * k_delta[i];
    b[i] = n[i].dot(delta_anchor[i]);
  }
  m.row(2) = g[0].transpose() * k_delta[0] - g[1].transpose() * k_delta[1];
  b[2] = g[0].dot(delta_anchor[0]) - g[1].dot(delta_anchor[1]);
  // Cramer's rule; (near-)singular systems are degenerate configurations.
  const Eigen::Vector3d c0 = m.row(1).cross(m.row(2)).transpose();
  const double det = m.row(0).dot(c0);
  const double hadamard = m.row(0).norm() * m.row(1).norm() * m.row(2).norm();
  if (!(std::abs(det) > 1e-12 * hadamard) || !std::isfinite(det)) return 0;
  const Eigen::Vector3d c1 = m.row(2).cross(m.row(0)).transpose();
  const Eigen::Vector3d c2 = m.row(0).cross(m.row(1)).transpose();
  const Eigen::Vector3d y = (c0 * b[0] + c1 * b[1] + c2 * b[2]) / det;
  const double scale = std::sqrt(y[0] * y[0] + y[1] * y[1]);
  if (!(scale > 0) || !(y[2] > 0) || !y.allFinite()) return 0;
  const double lambda0 = -g[0].dot(k_delta[0] * y - delta_anchor[0]);
  const Eigen::Vector3d& x0 = points_local[0];
  const Eigen::Vector3d t = anchor[0] + lambda0 * v0 -
                            (y[0] * upright::A(x0) + y[1] * upright::B(x0) + y[2] * upright::D(x0));
  if (!t.allFinite()) return 0;
  const Sim3d world_from_local(scale, upright::RotationY(y[0], y[1]), t);
  out->push_back(world_from_local.Inverse());
  return 1;
}

}  // namespace linecloud
