#include "linecloud/solvers/p3p.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

namespace linecloud {
namespace {

// One real root of c3 x³ + c2 x² + c1 x + c0, c3 ≠ 0 (a real cubic always has
// one): Cardano when the root is unique, the smallest of three otherwise;
// Newton-polished.
double OneRealCubicRoot(double c3, double c2, double c1, double c0) {
  const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
  const double q = (a * a - 3 * b) * (1.0 / 9);
  const double r = (2 * a * a * a - 9 * a * b + 27 * c) * (1.0 / 54);
  const double q3 = q * q * q;
  double x;
  if (r * r < q3) {
    const double sq = std::sqrt(q);
    x = -2 * sq * std::cos(std::acos(std::clamp(r / (sq * q), -1.0, 1.0)) * (1.0 / 3)) - a / 3;
  } else {
    const double big_a = -std::copysign(std::cbrt(std::abs(r) + std::sqrt(r * r - q3)), r);
    x = (big_a == 0 ? 0 : big_a + q / big_a) - a / 3;
  }
  for (int it = 0; it < 2; ++it) {
    const double f = ((x + a) * x + b) * x + c;
    const double df = (3 * x + 2 * a) * x + b;
    const double step = f / df;
    if (std::isfinite(step)) x -= step;
  }
  return x;
}

Eigen::Matrix3d Adjugate(const Eigen::Matrix3d& m) {
  Eigen::Matrix3d a;
  a.col(0) = m.row(1).cross(m.row(2)).transpose();
  a.col(1) = m.row(2).cross(m.row(0)).transpose();
  a.col(2) = m.row(0).cross(m.row(1)).transpose();
  return a;
}

}  // namespace

int p3p(std::span<const Eigen::Vector3d> bearings,
        std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  out->clear();
  std::array<Eigen::Vector3d, 3> y;
  for (int i = 0; i < 3; ++i) {
    const double n2 = bearings[i].squaredNorm();
    if (!(n2 > 0) || !std::isfinite(n2) || !points[i].allFinite()) return 0;
    y[i] = bearings[i] * (1 / std::sqrt(n2));
  }
  // World triangle X = [x01, x02, x01 × x02]; its inverse turns every solution's
  // camera-frame triangle into R = Y X⁻¹ (X⁻¹ rows: (x02 × n, n × x01, n) / |n|²).
  const Eigen::Vector3d x01 = points[1] - points[0], x02 = points[2] - points[0];
  const double a12 = x01.squaredNorm(), a13 = x02.squaredNorm();
  const double a23 = (points[2] - points[1]).squaredNorm();
  const Eigen::Vector3d n = x01.cross(x02);
  const double n2 = n.squaredNorm();
  if (!(a12 > 0 && a13 > 0 && a23 > 0) || !(n2 > 1e-24 * a12 * a13)) return 0;
  const double inv_n2 = 1 / n2;
  const Eigen::Vector3d g0 = x02.cross(n) * inv_n2, g1 = n.cross(x01) * inv_n2, g2 = n * inv_n2;

  const double b12 = -2 * y[0].dot(y[1]), b13 = -2 * y[0].dot(y[2]), b23 = -2 * y[1].dot(y[2]);
  // λ_i² + λ_j² + b_ij λ_i λ_j = a_ij as Λᵀ M_ij Λ = a_ij; the homogeneous
  // conics Λᵀ D1 Λ = 0 and Λᵀ D2 Λ = 0 eliminate the scale.
  // D1 = a23 M12 − a12 M23, D2 = a23 M13 − a13 M23.
  const double h12 = b12 / 2, h13 = b13 / 2, h23 = b23 / 2;
  Eigen::Matrix3d d1, d2;
  d1 << a23, a23 * h12, 0, a23 * h12, a23 - a12, -a12 * h23, 0, -a12 * h23, -a12;
  d2 << a23, 0, a23 * h13, 0, -a13, -a13 * h23, a23 * h13, -a13 * h23, a23 - a13;
  // det(D1 + γ D2) = det D1 + γ tr(adj(D1) D2) + γ² tr(D1 adj(D2)) + γ³ det D2.
  // Every real intersection of the conics lies on each degenerate member of the
  // pencil, and whenever one exists every real degenerate member is a pair of
  // real lines — so one real root suffices. It is taken on the side (γ or 1/γ)
  // with the larger leading coefficient.
  const double c3 = d2.determinant(), c0 = d1.determinant();
  const double c2 = (d1.cwiseProduct(Adjugate(d2).transpose())).sum();
  const double c1 = (Adjugate(d1).cwiseProduct(d2.transpose())).sum();
  Eigen::Matrix3d d0, dr;  // the degenerate member, and one independent of it
  if (std::abs(c3) >= std::abs(c0)) {
    const double gamma = c3 == 0 ? 0.0 : OneRealCubicRoot(c3, c2, c1, c0);
    d0 = d1 + gamma * d2;
    dr = d2 - gamma * d1;
  } else {
    const double mu = OneRealCubicRoot(c0, c1, c2, c3);
    d0 = mu * d1 + d2;
    dr = d1 - mu * d2;
  }
  if (!d0.allFinite()) return 0;

  // Split D0 = l mᵀ + m lᵀ into its lines: adj(D0) = −p pᵀ with p = l × m, and
  // D0 + [p]× has rank one, its rows ∝ one line and its columns ∝ the other.
  const Eigen::Matrix3d adj = Adjugate(d0);
  Eigen::Index i;
  const double minus_beta2 = adj.diagonal().minCoeff(&i);
  std::array<Eigen::Vector3d, 2> lines;
  int num_lines = 2;
  if (minus_beta2 < 0) {
    const Eigen::Vector3d p = adj.col(i) / std::sqrt(-minus_beta2);
    Eigen::Matrix3d c = d0;
    c(0, 1) -= p.z(); c(0, 2) += p.y(); c(1, 0) += p.z();
    c(1, 2) -= p.x(); c(2, 0) -= p.y(); c(2, 1) += p.x();
    Eigen::Index j, k;
    c.cwiseAbs().maxCoeff(&j, &k);
    lines[0] = c.row(j).transpose();
    lines[1] = c.col(k);
  } else if (adj.diagonal().maxCoeff() <= 0) {
    // adj(D0) = 0: a double line (rank one), the largest row of D0.
    Eigen::Index j;
    d0.rowwise().squaredNorm().maxCoeff(&j);
    lines[0] = d0.row(j).transpose();
    num_lines = 1;
  } else {
    return 0;  // complex conjugate lines: no real intersection
  }

  const double asum = a12 + a13 + a23;
  std::array<Eigen::Vector3d, 4> depths;
  int num_depths = 0;
  for (int l = 0; l < num_lines; ++l) {
    // Rays Λ = α u + β w in the plane lᵀΛ = 0 with Λᵀ Dr Λ = 0.
    const Eigen::Vector3d& normal = lines[l];
    Eigen::Index axis;
    normal.cwiseAbs().minCoeff(&axis);
    const Eigen::Vector3d u = normal.cross(Eigen::Vector3d::Unit(axis));
    const Eigen::Vector3d w = normal.cross(u);
    const Eigen::Vector3d dr_u = dr * u;
    const double q11 = u.dot(dr_u), q12 = w.dot(dr_u), q22 = w.dot(dr * w);
    const bool alpha_first = std::abs(q11) >= std::abs(q22);
    const double lead = alpha_first ? q11 : q22, tail = alpha_first ? q22 : q11;
    const double disc = q12 * q12 - lead * tail;
    if (!(disc >= 0) || lead == 0) continue;
    const double root_disc = std::sqrt(disc);
    for (const double tau : {(-q12 + root_disc) / lead, (-q12 - root_disc) / lead}) {
      const Eigen::Vector3d ray = alpha_first ? Eigen::Vector3d(tau * u + w) : Eigen::Vector3d(u + tau * w);
      // Λᵀ(M12 + M13 + M23)Λ = a12 + a13 + a23 fixes the scale.
      const double denom = 2 * ray.squaredNorm() + b12 * ray[0] * ray[1] +
                           b13 * ray[0] * ray[2] + b23 * ray[1] * ray[2];
      if (!(denom > 0)) continue;
      Eigen::Vector3d lam = std::sqrt(asum / denom) * ray;
      if (lam.sum() < 0) lam = -lam;
      if (!(lam.array() > 0).all()) continue;
      // Newton steps on the three inhomogeneous equations (Cramer's rule).
      for (int it = 0; it < 3; ++it) {
        const double l0 = lam[0], l1 = lam[1], l2 = lam[2];
        const Eigen::Vector3d r(l0 * l0 + l1 * l1 + b12 * l0 * l1 - a12,
                                l0 * l0 + l2 * l2 + b13 * l0 * l2 - a13,
                                l1 * l1 + l2 * l2 + b23 * l1 * l2 - a23);
        if (r.cwiseAbs().maxCoeff() <= 1e-15 * asum) break;
        Eigen::Matrix3d jac;
        jac << 2 * l0 + b12 * l1, 2 * l1 + b12 * l0, 0,
            2 * l0 + b13 * l2, 0, 2 * l2 + b13 * l0,
            0, 2 * l1 + b23 * l2, 2 * l2 + b23 * l1;
        const Eigen::Matrix3d jadj = Adjugate(jac);
        const double det = jac.row(0).dot(jadj.col(0));
        const Eigen::Vector3d step = jadj * r / det;
        if (!step.allFinite()) break;
        lam -= step;
      }
      if (!lam.allFinite() || !(lam.array() > 0).all()) continue;
      bool duplicate = false;
      for (int d = 0; d < num_depths; ++d) {
        duplicate |= (depths[d] - lam).squaredNorm() < 1e-18 * lam.squaredNorm();
      }
      if (!duplicate) depths[num_depths++] = lam;
    }
  }

  for (int d = 0; d < num_depths; ++d) {
    const Eigen::Vector3d& lam = depths[d];
    const Eigen::Vector3d p0 = lam[0] * y[0];
    const Eigen::Vector3d y01 = lam[1] * y[1] - p0, y02 = lam[2] * y[2] - p0;
    const Eigen::Matrix3d r = y01 * g0.transpose() + y02 * g1.transpose() +
                              y01.cross(y02) * g2.transpose();
    const Eigen::Vector3d t = p0 - r * points[0];
    if (r.allFinite() && t.allFinite()) {
      out->emplace_back(Eigen::Quaterniond(r).normalized(), t);
    }
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
