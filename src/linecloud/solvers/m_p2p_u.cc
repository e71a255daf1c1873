#include "linecloud/solvers/m_p2p_u.h"

#include "linecloud/solvers/upright.h"

namespace linecloud {

int m_p2p_u(std::span<const Eigen::Vector3d> origins,
            std::span<const Eigen::Vector3d> directions,
            std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  out->clear();
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
  const Eigen::Vector3d dx = points[0] - points[1];
  const Eigen::Vector3d dorigin = origins[0] - origins[1];
  // Scaled to unit |n|: α, β, γ then carry the lengths of the problem only.
  const double inverse_norm = 1 / std::sqrt(n2);
  const double alpha = n.dot(upright::A(dx)) * inverse_norm;
  const double beta = n.dot(upright::B(dx)) * inverse_norm;
  const double gamma = n.dot(upright::D(dx) - dorigin) * inverse_norm;
  double cs[2][2];
  const int count = upright::IntersectLineUnitCircle(alpha, beta, gamma, cs);
  for (int k = 0; k < count; ++k) {
    const double c = cs[k][0], s = cs[k][1];
    // R ΔX − Δo = λ₁ d₁ − λ₂ d₂ exactly on this line; crossing with d₂
    // gives λ₁ n, and t = o₁ + λ₁ d₁ − R X₁ (both rays are then met).
    const Eigen::Vector3d rhs =
        c * upright::A(dx) + s * upright::B(dx) + upright::D(dx) - dorigin;
    const double lambda1 = rhs.cross(d2).dot(n) / n2;
    const Eigen::Vector3d rotated =
        c * upright::A(points[0]) + s * upright::B(points[0]) + upright::D(points[0]);
    const Eigen::Vector3d t = origins[0] + lambda1 * d1 - rotated;
    if (!t.allFinite()) continue;
    out->emplace_back(upright::RotationY(c, s), t);
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
