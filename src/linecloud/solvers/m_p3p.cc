#include "linecloud/solvers/m_p3p.h"

#include "linecloud/util/check.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/LU>

#include "linecloud/solvers/depth_newton.h"
#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/triad.h"

namespace linecloud {
namespace {

// Bivariate polynomial in (λ1, λ2) of total degree ≤ D: c[i][j] λ1^i λ2^j
// (entries with i + j > D stay zero). The degrees are template arguments so
// the products below are straight-line code over the non-zero terms only.
template <int D>
struct Bi {
  std::array<std::array<double, D + 1>, D + 1> c{};
};

template <int A, int B>
Bi<std::max(A, B)> operator-(const Bi<A>& a, const Bi<B>& b) {
  Bi<std::max(A, B)> r;
  for (int i = 0; i <= A; ++i)
    for (int j = 0; i + j <= A; ++j) r.c[i][j] = a.c[i][j];
  for (int i = 0; i <= B; ++i)
    for (int j = 0; i + j <= B; ++j) r.c[i][j] -= b.c[i][j];
  return r;
}
template <int A, int B>
Bi<std::max(A, B)> operator+(const Bi<A>& a, const Bi<B>& b) {
  Bi<std::max(A, B)> r;
  for (int i = 0; i <= A; ++i)
    for (int j = 0; i + j <= A; ++j) r.c[i][j] = a.c[i][j];
  for (int i = 0; i <= B; ++i)
    for (int j = 0; i + j <= B; ++j) r.c[i][j] += b.c[i][j];
  return r;
}
template <int A, int B>
Bi<A + B> operator*(const Bi<A>& a, const Bi<B>& b) {
  Bi<A + B> r;
  for (int i = 0; i <= A; ++i)
    for (int j = 0; i + j <= A; ++j)
      for (int k = 0; k <= B; ++k)
        for (int l = 0; k + l <= B; ++l) r.c[i + k][j + l] += a.c[i][j] * b.c[k][l];
  return r;
}

// Linear b0 + b1 x and monic quadratic c0 + c1 x + x² in one variable.
struct Lin {
  double b0, b1;
  double operator()(double x) const { return b0 + b1 * x; }
};
struct MonicQuad {
  double c0, c1;
  double operator()(double x) const { return c0 + (c1 + x) * x; }
};

struct Equation {  // λi² + λj² − 2 c λiλj + 2 p λi − 2 q λj + r = 0
  double c, p, q, r;
  double Eval(double li, double lj) const {
    return li * li + lj * lj - 2 * c * li * lj + 2 * p * li - 2 * q * lj + r;
  }
  double DLi(double li, double lj) const { return 2 * li - 2 * c * lj + 2 * p; }
  double DLj(double li, double lj) const { return 2 * lj - 2 * c * li - 2 * q; }
};

Equation MakeEquation(const Eigen::Vector3d& oi, const Eigen::Vector3d& di,
                      const Eigen::Vector3d& oj, const Eigen::Vector3d& dj,
                      double squared_distance) {
  const Eigen::Vector3d oij = oi - oj;
  return {di.dot(dj), di.dot(oij), dj.dot(oij), oij.squaredNorm() - squared_distance};
}

// Roots of x² + b x + c.
int Quadratic(double b, double c, double roots[2]) {
  const double disc = b * b - 4 * c;
  if (disc < 0) return 0;
  const double s = std::sqrt(disc);
  const double q = -0.5 * (b + (b >= 0 ? s : -s));
  if (q == 0) {
    roots[0] = 0;
    return 1;
  }
  roots[0] = q;
  roots[1] = c / q;
  return 2;
}

}  // namespace

int m_p3p(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
          std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out,
          bool positive_depths) {
  CheckMinimalSample("m_p3p", 3, out, origins, directions, points);
  out->clear();
  // Normalise: centre both sides and scale by the map triangle's size.
  const Eigen::Vector3d cx = (points[0] + points[1] + points[2]) / 3.0;
  const Eigen::Vector3d co = (origins[0] + origins[1] + origins[2]) / 3.0;
  const double scale = std::sqrt(((points[0] - cx).squaredNorm() + (points[1] - cx).squaredNorm() +
                                  (points[2] - cx).squaredNorm()) /
                                 3.0);
  if (!(scale > 0) || !std::isfinite(scale)) return 0;
  std::array<Eigen::Vector3d, 3> x, o, d;
  for (int i = 0; i < 3; ++i) {
    const double dn = directions[i].norm();
    if (!(dn > 0) || !std::isfinite(dn) || !origins[i].allFinite()) return 0;
    x[i] = (points[i] - cx) / scale;
    o[i] = (origins[i] - co) / scale;
    d[i] = directions[i] / dn;
  }
  const Equation e12 = MakeEquation(o[0], d[0], o[1], d[1], (x[0] - x[1]).squaredNorm());
  const Equation e13 = MakeEquation(o[0], d[0], o[2], d[2], (x[0] - x[2]).squaredNorm());
  const Equation e23 = MakeEquation(o[1], d[1], o[2], d[2], (x[1] - x[2]).squaredNorm());

  // E13 and E23 as monic quadratics in λ3: λ3² + B λ3 + C, B linear and C a
  // monic quadratic in λ1 (E13) or λ2 (E23).
  const Lin b1{-2 * e13.q, -2 * e13.c}, b2{-2 * e23.q, -2 * e23.c};
  const MonicQuad c1{e13.r, 2 * e13.p}, c2{e23.r, 2 * e23.p};
  Bi<1> B1, B2;
  Bi<2> C1, C2;
  B1.c[0][0] = b1.b0, B1.c[1][0] = b1.b1;
  C1.c[0][0] = c1.c0, C1.c[1][0] = c1.c1, C1.c[2][0] = 1;
  B2.c[0][0] = b2.b0, B2.c[0][1] = b2.b1;
  C2.c[0][0] = c2.c0, C2.c[0][1] = c2.c1, C2.c[0][2] = 1;
  // Resultant in λ3: (C2 − C1)² + (B2 − B1)[(B2 − B1) C1 − B1 (C2 − C1)].
  const Bi<1> dB = B2 - B1;
  const Bi<2> dC = C2 - C1;
  const Bi<4> f = dC * dC + dB * (dB * C1 - B1 * dC);
  // Reduce f modulo E12 = λ2² + b λ2 + c (b, c in λ1): f ≡ G1 λ2 + G0.
  // g[j] (the coefficient of λ2^j) has degree ≤ 4 − j in λ1, and stays so.
  const Lin b{-2 * e12.q, -2 * e12.c};
  const MonicQuad c{e12.r, 2 * e12.p};
  std::array<std::array<double, 5>, 5> g;
  for (int j = 0; j < 5; ++j)
    for (int i = 0; i < 5; ++i) g[j][i] = f.c[i][j];
  for (int j = 4; j >= 2; --j) {
    for (int i = 0; i + j <= 4; ++i) {
      const double gi = g[j][i];
      g[j - 1][i] -= b.b0 * gi;
      g[j - 1][i + 1] -= b.b1 * gi;
      g[j - 2][i] -= c.c0 * gi;
      g[j - 2][i + 1] -= c.c1 * gi;
      g[j - 2][i + 2] -= gi;
    }
  }
  const std::array<double, 5>& g0 = g[0];
  const std::array<double, 5>& g1 = g[1];
  const auto eval4 = [](const std::array<double, 5>& p, double x) {
    return (((p[4] * x + p[3]) * x + p[2]) * x + p[1]) * x + p[0];
  };
  // G0² − b G0 G1 + c G1², degree 8 in λ1.
  double g00[9] = {}, g01[9] = {}, g11[9] = {}, univariate[9] = {};
  for (int i = 0; i < 5; ++i)
    for (int k = 0; k < 5; ++k) {
      g00[i + k] += g0[i] * g0[k];
      if (i + k < 8) g01[i + k] += g0[i] * g1[k];
      if (i + k < 7) g11[i + k] += g1[i] * g1[k];
    }
  for (int i = 0; i < 9; ++i) {
    univariate[i] = g00[i] - b.b0 * g01[i] + c.c0 * g11[i];
    if (i >= 1) univariate[i] += -b.b1 * g01[i - 1] + c.c1 * g11[i - 1];
    if (i >= 2) univariate[i] += g11[i - 2];
  }
  double roots1[8];
  const int num_roots1 = poly::SturmRealRoots(univariate, 8, roots1);

  std::array<Eigen::Vector3d, 8> depths;
  int num_depths = 0;
  for (int r1 = 0; r1 < num_roots1; ++r1) {
    const double l1 = roots1[r1];
    double l2s[2];
    int n2;
    const double g1v = eval4(g1, l1), g0v = eval4(g0, l1);
    if (std::abs(g1v) > 1e-10 * (std::abs(g0v) + 1e-300)) {
      l2s[0] = -g0v / g1v;
      n2 = 1;
    } else {
      n2 = Quadratic(b(l1), c(l1), l2s);
    }
    for (int k2 = 0; k2 < n2; ++k2) {
      const double l2 = l2s[k2];
      double l3s[2];
      int n3;
      const double den = b1(l1) - b2(l2);
      const double num = c1(l1) - c2(l2);
      if (std::abs(den) > 1e-10 * (std::abs(num) + 1e-300)) {
        l3s[0] = -num / den;
        n3 = 1;
      } else {
        n3 = Quadratic(b1(l1), c1(l1), l3s);
      }
      for (int k3 = 0; k3 < n3; ++k3) {
        // Newton polish on the three distance equations.
        double m0 = l1, m1 = l2, m2 = l3s[k3];
        for (int it = 0; it < 8; ++it) {
          const double r0 = e12.Eval(m0, m1), r1 = e13.Eval(m0, m2), r2 = e23.Eval(m1, m2);
          if (std::max({std::abs(r0), std::abs(r1), std::abs(r2)}) <= 1e-15) break;
          double s0, s1, s2;
          if (!SolvePairwiseJacobian(e12.DLi(m0, m1), e12.DLj(m0, m1), e13.DLi(m0, m2),
                                     e13.DLj(m0, m2), e23.DLi(m1, m2), e23.DLj(m1, m2), r0, r1, r2,
                                     &s0, &s1, &s2)) {
            break;
          }
          m0 -= s0, m1 -= s1, m2 -= s2;
          const double step2 = s0 * s0 + s1 * s1 + s2 * s2;
          const double size = 1.0 + std::sqrt(m0 * m0 + m1 * m1 + m2 * m2);
          if (step2 < 1e-30 * size * size) break;
        }
        const Eigen::Vector3d lam(m0, m1, m2);
        const double residual = std::abs(e12.Eval(lam[0], lam[1])) +
                                std::abs(e13.Eval(lam[0], lam[2])) +
                                std::abs(e23.Eval(lam[1], lam[2]));
        if (!(residual < 1e-9) || !lam.allFinite()) continue;
        if (positive_depths && !(lam.array() > 0).all()) continue;
        bool duplicate = false;
        for (int d = 0; d < num_depths; ++d) {
          duplicate |= (depths[d] - lam).norm() < 1e-9 * (1 + lam.norm());
        }
        if (!duplicate && num_depths < static_cast<int>(depths.size())) depths[num_depths++] = lam;
      }
    }
  }

  for (int k = 0; k < num_depths; ++k) {
    const Eigen::Vector3d& lam = depths[k];
    std::array<Eigen::Vector3d, 3> p;
    for (int i = 0; i < 3; ++i) p[i] = o[i] + lam[i] * d[i];
    Eigen::Matrix3d r;
    if (!TriadRotation(x[1] - x[0], x[2] - x[0], p[1] - p[0], p[2] - p[0], &r)) continue;
    const Eigen::Vector3d t_normalized = (p[0] + p[1] + p[2]) / 3.0;  // R·0 + t
    const Eigen::Vector3d t = scale * t_normalized - r * cx + co;
    if (!t.allFinite()) continue;
    out->emplace_back(Eigen::Quaterniond(r), t);
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
