#include "linecloud/solvers/p3p.h"

#include "linecloud/util/check.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Geometry>

#include "linecloud/solvers/depth_newton.h"

namespace linecloud {
namespace {

// One real root of c3 x³ + c2 x² + c1 x + c0, c3 ≠ 0 (a real cubic always has
// one): Cardano when the root is unique, the smallest of three otherwise;
// one Newton step. *unique: the root is the only real one, with a margin
// (near a double root three real roots are assumed).
double OneRealCubicRoot(double c3, double c2, double c1, double c0, bool* unique) {
  const double inv_c3 = 1 / c3;
  const double a = c2 * inv_c3, b = c1 * inv_c3, c = c0 * inv_c3;
  const double q = (a * a - 3 * b) * (1.0 / 9);
  const double r = (2 * a * a * a - 9 * a * b + 27 * c) * (1.0 / 54);
  const double q3 = q * q * q;
  double x;
  *unique = r * r - q3 > 1e-6 * std::abs(q3);
  if (r * r < q3) {
    const double sq = std::sqrt(q);
    x = -2 * sq * std::cos(std::acos(std::clamp(r / (sq * q), -1.0, 1.0)) * (1.0 / 3)) - a / 3;
  } else {
    const double big_a = -std::copysign(std::cbrt(std::abs(r) + std::sqrt(r * r - q3)), r);
    x = (big_a == 0 ? 0 : big_a + q / big_a) - a / 3;
  }
  // One Newton step (the depths are polished again below).
  const double f = ((x + a) * x + b) * x + c;
  const double df = (3 * x + 2 * a) * x + b;
  const double step = f / df;
  return std::isfinite(step) ? x - step : x;
}

// A symmetric 3 × 3 matrix by its entries.
struct Sym3 {
  double e00, e01, e02, e11, e12, e22;
  template <int R, int C>
  double at() const {
    if constexpr (R > C) {
      return at<C, R>();
    } else if constexpr (R == 0) {
      return C == 0 ? e00 : C == 1 ? e01 : e02;
    } else {
      return R == 1 ? (C == 1 ? e11 : e12) : e22;
    }
  }
};

// The squared sides a_ij = |X_i − X_j|² and bearing cosines m_ij = f_i·f_j.
struct Triangle {
  double a01, a02, a12, m01, m02, m12;
};

// The rays Λ with positive depths on the line nᵀΛ = 0 where the conic
// ΛᵀFΛ = 0 vanishes, scaled by Q_ij(Λ) = a_ij; K is the largest |n_K|.
// Λ_K = c_i Λ_i + c_j Λ_j, and with τ = Λ_i / Λ_j the conic is a quadratic in
// τ. Returns the number of rays (0 to 2), or −1 when the line holds no real
// intersection at all.
template <int K>
int CutLine(const Eigen::Vector3d& n, const Sym3& f, const Triangle& tri, Eigen::Vector3d* rays) {
  constexpr int I = K == 0 ? 1 : 0, J = K == 2 ? 1 : 2;
  const double inv_nk = -1 / n[K];
  const double ci = n[I] * inv_nk, cj = n[J] * inv_nk;
  const double fkk = f.at<K, K>(), fik = f.at<I, K>(), fjk = f.at<J, K>();
  const double qa = f.at<I, I>() + ci * (2 * fik + ci * fkk);
  const double qb = f.at<I, J>() + ci * fjk + cj * (fik + ci * fkk);
  const double qc = f.at<J, J>() + cj * (2 * fjk + cj * fkk);
  const double disc = qb * qb - qa * qc;
  if (!(disc >= 0)) return -1;
  const double aij = K == 0 ? tri.a12 : K == 1 ? tri.a02 : tri.a01;
  const double mij = K == 0 ? tri.m12 : K == 1 ? tri.m02 : tri.m01;
  const double q = -(qb + std::copysign(std::sqrt(disc), qb));
  int num_rays = 0;
  const auto add = [&](double tau) {
    const double w = ci * tau + cj;
    if (!(tau > 0 && w > 0)) return;
    const double dj = std::sqrt(aij / (tau * (tau - 2 * mij) + 1));
    Eigen::Vector3d& lam = rays[num_rays++];
    lam[I] = tau * dj;
    lam[J] = dj;
    lam[K] = w * dj;
  };
  if (qa != 0) add(q / qa);
  if (q != 0) add(qc / q);
  return num_rays;
}

}  // namespace

int p3p(std::span<const Eigen::Vector3d> bearings, std::span<const Eigen::Vector3d> points,
        std::vector<Rigid3d>* out) {
  CheckMinimalSample("p3p", 3, out, bearings, points);
  out->clear();
  for (int i = 0; i < 3; ++i) {
    if (!bearings[i].allFinite() || !points[i].allFinite()) return 0;
  }
  // Renumber so that the longest side joins points 1 and 2: the depth ratios
  // below are then a, b ≤ 1 and the scale equation the best conditioned.
  const double d01 = (points[0] - points[1]).squaredNorm();
  const double d02 = (points[0] - points[2]).squaredNorm();
  const double d12 = (points[1] - points[2]).squaredNorm();
  std::array<int, 3> order = {0, 1, 2};
  double a01 = d01, a02 = d02, a12 = d12;  // |X_i − X_j|² after renumbering
  if (d01 >= d02 && d01 >= d12) {
    order = {2, 0, 1};
    a01 = d02, a02 = d12, a12 = d01;
  } else if (d02 >= d12) {
    order = {1, 0, 2};
    a02 = d12, a12 = d02;
  }
  std::array<Eigen::Vector3d, 3> y, x;
  for (int i = 0; i < 3; ++i) {
    const Eigen::Vector3d& f = bearings[order[i]];
    const double n2 = f.squaredNorm();
    if (!(n2 > 0)) return 0;
    y[i] = n2 == 1 ? f : Eigen::Vector3d(f * (1 / std::sqrt(n2)));
    x[i] = points[order[i]];
  }
  // World triangle X = [x01, x02, x01 × x02]; its inverse turns every solution's
  // camera-frame triangle into R = Y X⁻¹ (X⁻¹ rows: (x02 × n, n × x01, n) / |n|²).
  const Eigen::Vector3d x01 = x[1] - x[0], x02 = x[2] - x[0];
  const Eigen::Vector3d n = x01.cross(x02);
  const double n2 = n.squaredNorm();
  if (!(a01 > 0 && a02 > 0 && a12 > 0) || !(n2 > 1e-24 * a01 * a02)) return 0;
  const double inv_n2 = 1 / n2;
  const Eigen::Vector3d g0 = x02.cross(n) * inv_n2, g1 = n.cross(x01) * inv_n2, g2 = n * inv_n2;

  // λ_i² + λ_j² − 2 m_ij λ_i λ_j = a_ij (m_ij = f_i·f_j). Divided by a12 and
  // with a = a01 / a12, b = a02 / a12, the scale drops out:
  //   F1(Λ) = Q01(Λ) − a Q12(Λ) = 0,   F2(Λ) = Q02(Λ) − b Q12(Λ) = 0,
  // two homogeneous conics, Fk = Λᵀ Mk Λ. det(M1 + s M2) is the cubic
  // c3 s³ + c2 s² + c1 s + c0 below (u_ij = 1 − m_ij², t = m01 m02 m12);
  // approach of Ding et al., "Revisiting the P3P Problem", CVPR 2023.
  const double m01 = y[0].dot(y[1]), m02 = y[0].dot(y[2]), m12 = y[1].dot(y[2]);
  const double inv_a12 = 1 / a12;
  const double a = a01 * inv_a12, b = a02 * inv_a12;
  const double u01 = 1 - m01 * m01, u02 = 1 - m02 * m02, u12 = 1 - m12 * m12;
  const double t1 = m01 * m02 * m12 - 1;
  const double c3 = b * (b * u12 - u02);
  const double c2 = b * u12 * (2 * a + b) + (1 - a) * u02 + 2 * b * t1;
  const double c1 = a * u12 * (a + 2 * b) + (1 - b) * u01 + 2 * a * t1;
  const double c0 = a * (a * u12 - u01);
  const Sym3 m1{1, -m01, 0, 1 - a, a * m12, -a};
  const Sym3 m2{1, 0, -m02, -b, b * m12, 1 - b};
  // Every real intersection of the conics lies on each degenerate member
  // α M1 + β M2 of the pencil, and whenever one exists every real degenerate
  // member is a pair of real lines — so one real root suffices, taken on the
  // side (s = β/α or 1/s) with the larger leading coefficient.
  double alpha = 1, beta = 0;
  bool unique = false;
  if (std::abs(c3) >= std::abs(c0)) {
    beta = c3 == 0 ? 0.0 : OneRealCubicRoot(c3, c2, c1, c0, &unique);
  } else {
    alpha = OneRealCubicRoot(c0, c1, c2, c3, &unique);
    beta = 1;
  }
  if (!std::isfinite(alpha) || !std::isfinite(beta)) return 0;
  const Sym3 c{alpha * m1.e00 + beta * m2.e00,
               alpha * m1.e01,
               beta * m2.e02,
               alpha * m1.e11 + beta * m2.e11,
               alpha * m1.e12 + beta * m2.e12,
               alpha * m1.e22 + beta * m2.e22};
  // On a line of the member αF1 + βF2 vanishes, so there F1 = −(β/α) F2: the
  // conic with the smaller weight in the member is nearly zero along the line
  // (cancellation); the line is cut with the other one.
  const Sym3& f = std::abs(alpha) >= std::abs(beta) ? m2 : m1;

  // Split C = l mᵀ + m lᵀ into its lines: adj(C) = −p pᵀ with p = l × m, and
  // C + [p]× = 2 m lᵀ has rank one, its rows ∝ one line and its columns ∝ the other.
  const double adj00 = c.e11 * c.e22 - c.e12 * c.e12;
  const double adj11 = c.e00 * c.e22 - c.e02 * c.e02;
  const double adj22 = c.e00 * c.e11 - c.e01 * c.e01;
  std::array<Eigen::Vector3d, 2> lines;
  int num_lines = 2;
  const double min_diag = std::min({adj00, adj11, adj22});
  if (min_diag < 0) {
    Eigen::Vector3d p;
    if (min_diag == adj00) {
      p = Eigen::Vector3d(adj00, c.e02 * c.e12 - c.e01 * c.e22, c.e01 * c.e12 - c.e02 * c.e11);
    } else if (min_diag == adj11) {
      p = Eigen::Vector3d(c.e02 * c.e12 - c.e01 * c.e22, adj11, c.e01 * c.e02 - c.e00 * c.e12);
    } else {
      p = Eigen::Vector3d(c.e01 * c.e12 - c.e02 * c.e11, c.e01 * c.e02 - c.e00 * c.e12, adj22);
    }
    p *= 1 / std::sqrt(-min_diag);
    Eigen::Matrix3d r;
    r << c.e00, c.e01 - p.z(), c.e02 + p.y(), c.e01 + p.z(), c.e11, c.e12 - p.x(), c.e02 - p.y(),
        c.e12 + p.x(), c.e22;
    int j = 0, k = 0;
    double largest = -1;
    for (int row = 0; row < 3; ++row) {
      for (int col = 0; col < 3; ++col) {
        if (std::abs(r(row, col)) > largest) largest = std::abs(r(row, col)), j = row, k = col;
      }
    }
    lines[0] = r.row(j).transpose();
    lines[1] = r.col(k);
  } else if (std::max({adj00, adj11, adj22}) <= 0) {
    // adj(C) = 0: a double line (rank one), the largest row of C.
    Eigen::Matrix3d full;
    full << c.e00, c.e01, c.e02, c.e01, c.e11, c.e12, c.e02, c.e12, c.e22;
    Eigen::Index j;
    full.rowwise().squaredNorm().maxCoeff(&j);
    lines[0] = full.row(j).transpose();
    num_lines = 1;
  } else {
    return 0;  // complex conjugate lines: no real intersection
  }

  const double b01 = -2 * m01, b02 = -2 * m02, b12 = -2 * m12;
  const double asum = a01 + a02 + a12;
  const Triangle tri{a01, a02, a12, m01, m02, m12};
  std::array<Eigen::Vector3d, 4> depths;
  int num_depths = 0;
  for (int l = 0; l < num_lines; ++l) {
    const Eigen::Vector3d& nl = lines[l];
    const double n0 = std::abs(nl[0]), n1 = std::abs(nl[1]), n2 = std::abs(nl[2]);
    const int k = n0 >= n1 ? (n0 >= n2 ? 0 : 2) : (n1 >= n2 ? 1 : 2);
    std::array<Eigen::Vector3d, 2> rays;
    const int num_rays = k == 0   ? CutLine<0>(nl, f, tri, rays.data())
                         : k == 1 ? CutLine<1>(nl, f, tri, rays.data())
                                  : CutLine<2>(nl, f, tri, rays.data());
    for (int r = 0; r < num_rays; ++r) {
      // Newton steps on the three inhomogeneous equations.
      double l0 = rays[r][0], l1 = rays[r][1], l2 = rays[r][2];
      for (int it = 0; it < 3; ++it) {
        const double r0 = l0 * l0 + l1 * l1 + b01 * l0 * l1 - a01;
        const double r1 = l0 * l0 + l2 * l2 + b02 * l0 * l2 - a02;
        const double r2 = l1 * l1 + l2 * l2 + b12 * l1 * l2 - a12;
        if (std::max({std::abs(r0), std::abs(r1), std::abs(r2)}) <= 1e-13 * asum) break;
        const double j00 = 2 * l0 + b01 * l1, j01 = 2 * l1 + b01 * l0;
        const double j10 = 2 * l0 + b02 * l2, j12 = 2 * l2 + b02 * l0;
        const double j21 = 2 * l1 + b12 * l2, j22 = 2 * l2 + b12 * l1;
        double s0, s1, s2;
        if (!SolvePairwiseJacobian(j00, j01, j10, j12, j21, j22, r0, r1, r2, &s0, &s1, &s2)) break;
        l0 -= s0, l1 -= s1, l2 -= s2;
      }
      const Eigen::Vector3d lam(l0, l1, l2);
      if (!lam.allFinite() || !(lam.array() > 0).all()) continue;
      bool duplicate = false;
      for (int d = 0; d < num_depths; ++d) {
        duplicate |= (depths[d] - lam).squaredNorm() < 1e-18 * lam.squaredNorm();
      }
      if (!duplicate) depths[num_depths++] = lam;
    }
    // A cubic with one real root means two real intersections and two complex
    // ones: both real ones lie on one line, the other line holds the complex pair.
    if (unique && num_rays >= 0) break;
  }

  for (int d = 0; d < num_depths; ++d) {
    const Eigen::Vector3d& lam = depths[d];
    const Eigen::Vector3d p0 = lam[0] * y[0];
    const Eigen::Vector3d y01 = lam[1] * y[1] - p0, y02 = lam[2] * y[2] - p0;
    const Eigen::Matrix3d r =
        y01 * g0.transpose() + y02 * g1.transpose() + y01.cross(y02) * g2.transpose();
    const Eigen::Vector3d t = p0 - r * x[0];
    if (r.allFinite() && t.allFinite()) {
      // The camera triangle is congruent to the world one, so R is a rotation
      // and its quaternion a unit one up to rounding.
      Eigen::Quaterniond q(r);
      if (!(std::abs(q.squaredNorm() - 1) < 1e-12)) q.normalize();
      out->emplace_back(q, t);
    }
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
