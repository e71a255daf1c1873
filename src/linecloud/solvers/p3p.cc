#include "linecloud/solvers/p3p.h"

#include <array>
#include <cmath>
#include <numbers>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>

#include "linecloud/solvers/triad.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

// Real roots of c3 x³ + c2 x² + c1 x + c0 (closed form, Newton-polished).
int SolveCubic(double c3, double c2, double c1, double c0, double roots[3]) {
  const double scale = std::max({std::abs(c3), std::abs(c2), std::abs(c1), std::abs(c0)});
  if (!(scale > 0) || !std::isfinite(scale)) return 0;
  int n = 0;
  if (std::abs(c3) < 1e-12 * scale) {
    if (std::abs(c2) < 1e-12 * scale) {
      if (c1 == 0) return 0;
      roots[0] = -c0 / c1;
      return 1;
    }
    const double disc = c1 * c1 - 4 * c2 * c0;
    if (disc < 0) return 0;
    const double q = -0.5 * (c1 + std::copysign(std::sqrt(disc), c1));
    roots[n++] = q / c2;
    if (q != 0) roots[n++] = c0 / q;
  } else {
    const double a = c2 / c3, b = c1 / c3, c = c0 / c3;
    const double q = (a * a - 3 * b) / 9;
    const double r = (2 * a * a * a - 9 * a * b + 27 * c) / 54;
    if (r * r < q * q * q) {
      const double theta = std::acos(std::clamp(r / std::sqrt(q * q * q), -1.0, 1.0));
      const double m = -2 * std::sqrt(q);
      roots[n++] = m * std::cos(theta / 3) - a / 3;
      roots[n++] = m * std::cos((theta + 2 * std::numbers::pi) / 3) - a / 3;
      roots[n++] = m * std::cos((theta - 2 * std::numbers::pi) / 3) - a / 3;
    } else {
      const double big_a = -std::copysign(std::cbrt(std::abs(r) + std::sqrt(r * r - q * q * q)), r);
      const double big_b = big_a == 0 ? 0 : q / big_a;
      roots[n++] = big_a + big_b - a / 3;
    }
  }
  for (int i = 0; i < n; ++i) {
    for (int it = 0; it < 2; ++it) {
      const double x = roots[i];
      const double f = ((c3 * x + c2) * x + c1) * x + c0;
      const double df = (3 * c3 * x + 2 * c2) * x + c1;
      if (df != 0 && std::isfinite(f / df)) roots[i] -= f / df;
    }
  }
  return n;
}

}  // namespace

int p3p(std::span<const Eigen::Vector3d> bearings,
        std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out) {
  out->clear();
  std::array<Eigen::Vector3d, 3> y;
  for (int i = 0; i < 3; ++i) {
    const double n = bearings[i].norm();
    if (!(n > 0) || !std::isfinite(n) || !points[i].allFinite()) return 0;
    y[i] = bearings[i] / n;
  }
  const double b12 = -2 * y[0].dot(y[1]), b13 = -2 * y[0].dot(y[2]), b23 = -2 * y[1].dot(y[2]);
  const double a12 = (points[0] - points[1]).squaredNorm();
  const double a13 = (points[0] - points[2]).squaredNorm();
  const double a23 = (points[1] - points[2]).squaredNorm();
  if (!(a12 > 0 && a13 > 0 && a23 > 0)) return 0;
  Eigen::Matrix3d m12, m13, m23;
  m12 << 1, b12 / 2, 0, b12 / 2, 1, 0, 0, 0, 0;
  m13 << 1, 0, b13 / 2, 0, 0, 0, b13 / 2, 0, 1;
  m23 << 0, 0, 0, 0, 1, b23 / 2, 0, b23 / 2, 1;
  // Homogeneous conics: Λᵀ D1 Λ = 0, Λᵀ D2 Λ = 0.
  const Eigen::Matrix3d d1 = a23 * m12 - a12 * m23;
  const Eigen::Matrix3d d2 = a23 * m13 - a13 * m23;
  const Eigen::Matrix3d msum = m12 + m13 + m23;
  const double asum = a12 + a13 + a23;
  // det(D1 + γ D2) = det D1 + γ tr(adj(D1) D2) + γ² tr(D1 adj(D2)) + γ³ det D2.
  const auto adjugate = [](const Eigen::Matrix3d& m) {
    Eigen::Matrix3d a;
    a.col(0) = m.row(1).cross(m.row(2)).transpose();
    a.col(1) = m.row(2).cross(m.row(0)).transpose();
    a.col(2) = m.row(0).cross(m.row(1)).transpose();
    return a;
  };
  double gammas[3];
  const int num_gammas = SolveCubic(d2.determinant(), (d1 * adjugate(d2)).trace(),
                                    (adjugate(d1) * d2).trace(), d1.determinant(), gammas);

  std::vector<Eigen::Vector3d> depths;
  for (int g = 0; g < num_gammas && depths.empty(); ++g) {
    const double gamma = gammas[g];
    if (!std::isfinite(gamma)) continue;
    const Eigen::Matrix3d d0 = d1 + gamma * d2;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es;
    es.computeDirect(d0);
    // The eigenvalue closest to zero belongs to the null direction.
    const Eigen::Vector3d ev = es.eigenvalues();
    Eigen::Index zero;
    ev.cwiseAbs().minCoeff(&zero);
    const int ia = zero == 0 ? 1 : 0, ib = zero == 2 ? 1 : 2;
    const double sa = ev[ia], sb = ev[ib];
    if (!(sa * sb < 0)) continue;  // complex pair of planes
    const Eigen::Vector3d ea = es.eigenvectors().col(ia), eb = es.eigenvectors().col(ib);
    const double s = std::sqrt(-sb / sa);
    const Eigen::Matrix3d& dr = std::abs(gamma) <= 1 ? d1 : d2;
    for (const double sign : {1.0, -1.0}) {
      const Eigen::Vector3d n = ea - sign * s * eb;
      Eigen::Vector3d p, q;
      upright::OrthogonalBasis(n, &p, &q);
      const double q11 = p.dot(dr * p), q12 = p.dot(dr * q), q22 = q.dot(dr * q);
      // Rays Λ0 in the plane with Λ0ᵀ Dr Λ0 = 0.
      std::array<Eigen::Vector3d, 2> rays;
      int num_rays = 0;
      const bool alpha_first = std::abs(q11) >= std::abs(q22);
      const double lead = alpha_first ? q11 : q22, tail = alpha_first ? q22 : q11;
      const double disc = q12 * q12 - lead * tail;
      if (disc < 0 || lead == 0) continue;
      const double root_disc = std::sqrt(disc);
      for (const double tau : {(-q12 + root_disc) / lead, (-q12 - root_disc) / lead}) {
        rays[num_rays++] = alpha_first ? Eigen::Vector3d(tau * p + q) : Eigen::Vector3d(p + tau * q);
      }
      for (int k = 0; k < num_rays; ++k) {
        const double denom = rays[k].dot(msum * rays[k]);
        if (!(denom > 0)) continue;
        Eigen::Vector3d lam = std::sqrt(asum / denom) * rays[k];
        if (lam.sum() < 0) lam = -lam;
        if (!(lam.array() > 0).all()) continue;
        // Gauss–Newton on the three inhomogeneous equations.
        for (int it = 0; it < 3; ++it) {
          const Eigen::Vector3d r(lam[0] * lam[0] + lam[1] * lam[1] + b12 * lam[0] * lam[1] - a12,
                                  lam[0] * lam[0] + lam[2] * lam[2] + b13 * lam[0] * lam[2] - a13,
                                  lam[1] * lam[1] + lam[2] * lam[2] + b23 * lam[1] * lam[2] - a23);
          Eigen::Matrix3d j;
          j << 2 * lam[0] + b12 * lam[1], 2 * lam[1] + b12 * lam[0], 0,
              2 * lam[0] + b13 * lam[2], 0, 2 * lam[2] + b13 * lam[0],
              0, 2 * lam[1] + b23 * lam[2], 2 * lam[2] + b23 * lam[1];
          const Eigen::Vector3d step = j.partialPivLu().solve(r);
          if (!step.allFinite()) break;
          lam -= step;
          if (step.norm() < 1e-15 * lam.norm()) break;
        }
        if (!lam.allFinite() || !(lam.array() > 0).all()) continue;
        bool duplicate = false;
        for (const Eigen::Vector3d& other : depths) {
          duplicate |= (other - lam).norm() < 1e-9 * lam.norm();
        }
        if (!duplicate) depths.push_back(lam);
      }
    }
  }

  for (const Eigen::Vector3d& lam : depths) {
    const Eigen::Vector3d p0 = lam[0] * y[0], p1 = lam[1] * y[1], p2 = lam[2] * y[2];
    Eigen::Matrix3d r;
    if (!TriadRotation(points[1] - points[0], points[2] - points[0], p1 - p0, p2 - p0, &r)) {
      continue;
    }
    const Eigen::Vector3d t =
        (p0 + p1 + p2) / 3.0 - r * ((points[0] + points[1] + points[2]) / 3.0);
    if (t.allFinite()) out->emplace_back(Eigen::Quaterniond(r), t);
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
