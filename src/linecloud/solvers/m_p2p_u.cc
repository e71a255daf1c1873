#include "linecloud/solvers/m_p2p_u.h"

#include "linecloud/util/check.h"

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p2p_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, UprightSolution solutions[2]) {
  CheckMinimalSample("m_p2p_u", 2, solutions, origins, directions, points);
  for (int i = 0; i < 2; ++i) {
    if (!(directions[i].squaredNorm() > 0) || !directions[i].allFinite() ||
        !points[i].allFinite() || !origins[i].allFinite()) {
      return 0;
    }
  }
  const Eigen::Vector3d& d1 = directions[0];
  const Eigen::Vector3d& d2 = directions[1];
  // The difference of the two constraints, R ΔX − Δo = λ₁ d₁ − λ₂ d₂, lies in
  // span(d₁, d₂): its component along n = d₁ × d₂ vanishes,
  //     nᵀ(c A(ΔX) + s B(ΔX) + D(ΔX) − Δo) = 0,
  // the line α c + β s + γ = 0 (the left null vector of the four projected
  // equations' t-block is n, up to scale).
  const Eigen::Vector3d n = d1.cross(d2);
  const double n2 = n.squaredNorm();
  if (!(n2 > 1e-24 * d1.squaredNorm() * d2.squaredNorm())) return 0;  // parallel rays
  // Scalar arithmetic: the products are read back as soon as they are
  // written, and small Eigen temporaries stall on store forwarding here.
  const double dx = points[0].x() - points[1].x(), dy = points[0].y() - points[1].y(),
               dz = points[0].z() - points[1].z();
  const double ox = origins[0].x() - origins[1].x(), oy = origins[0].y() - origins[1].y(),
               oz = origins[0].z() - origins[1].z();
  // Scaled to unit |n|: α, β, γ then carry the lengths of the problem only.
  const double inverse_norm = 1 / std::sqrt(n2);
  const double alpha = (n.x() * dx + n.z() * dz) * inverse_norm;  // nᵀA(ΔX)
  const double beta = (n.x() * dz - n.z() * dx) * inverse_norm;   // nᵀB(ΔX)
  const double gamma =
      (n.y() * dy - (n.x() * ox + n.y() * oy + n.z() * oz)) * inverse_norm;  // nᵀ(D(ΔX) − Δo)
  double cs[2][2];
  const int count = upright::IntersectLineUnitCircle(alpha, beta, gamma, cs);
  int num_solutions = 0;
  const double inv_n2 = 1 / n2;
  const Eigen::Vector3d m = d2.cross(n) * inv_n2;  // (rhs × d₂)·n / |n|² = rhs·(d₂ × n) / |n|²
  for (int k = 0; k < count; ++k) {
    const double c = cs[k][0], s = cs[k][1];
    // R ΔX − Δo = λ₁ d₁ − λ₂ d₂ exactly on this line; crossing with d₂
    // gives λ₁ n, and t = o₁ + λ₁ d₁ − R X₁ (both rays are then met).
    const double rx = c * dx + s * dz - ox, ry = dy - oy, rz = c * dz - s * dx - oz;
    const double lambda1 = rx * m.x() + ry * m.y() + rz * m.z();
    const Eigen::Vector3d& p = points[0];
    const Eigen::Vector3d t(origins[0].x() + lambda1 * d1.x() - (c * p.x() + s * p.z()),
                            origins[0].y() + lambda1 * d1.y() - p.y(),
                            origins[0].z() + lambda1 * d1.z() - (c * p.z() - s * p.x()));
    if (!t.allFinite()) continue;
    solutions[num_solutions++] = {c, s, t};
  }
  return num_solutions;
}

int m_p2p_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p2p_u", 2, out, origins, directions, points);
  out->clear();
  UprightSolution solutions[2];
  const int count = m_p2p_u(origins, directions, points, solutions);
  for (int k = 0; k < count; ++k) {
    out->emplace_back(upright::RotationYUnit(solutions[k].c, solutions[k].s), solutions[k].t);
  }
  return count;
}

}  // namespace linecloud
