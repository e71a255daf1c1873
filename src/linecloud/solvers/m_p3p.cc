#include "linecloud/solvers/m_p3p.h"

#include <array>
#include <cmath>

#include <Eigen/LU>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/triad.h"

namespace linecloud {
namespace {

using poly::Poly;

// Bivariate polynomial in (λ1, λ2) of degree <= 4 in each variable.
struct Bi {
  std::array<std::array<double, 5>, 5> c{};  // c[i][j]: λ1^i λ2^j

  static Bi InX(const Poly& p) {  // polynomial in λ1 only
    Bi b;
    for (size_t i = 0; i < p.size(); ++i) b.c[i][0] = p[i];
    return b;
  }
  static Bi InY(const Poly& p) {  // polynomial in λ2 only
    Bi b;
    for (size_t j = 0; j < p.size(); ++j) b.c[0][j] = p[j];
    return b;
  }
};

Bi operator+(const Bi& a, const Bi& b) {
  Bi r;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) r.c[i][j] = a.c[i][j] + b.c[i][j];
  return r;
}
Bi operator-(const Bi& a, const Bi& b) {
  Bi r;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) r.c[i][j] = a.c[i][j] - b.c[i][j];
  return r;
}
Bi operator*(const Bi& a, const Bi& b) {
  Bi r;
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) {
      if (a.c[i][j] == 0) continue;
      for (int k = 0; i + k < 5; ++k)
        for (int l = 0; j + l < 5; ++l) r.c[i + k][j + l] += a.c[i][j] * b.c[k][l];
    }
  return r;
}

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

int m_p3p(std::span<const Eigen::Vector3d> origins,
          std::span<const Eigen::Vector3d> directions,
          std::span<const Eigen::Vector3d> points, std::vector<Rigid3d>* out,
          bool positive_depths) {
  out->clear();
  // Normalise: centre both sides and scale by the map triangle's size.
  const Eigen::Vector3d cx = (points[0] + points[1] + points[2]) / 3.0;
  const Eigen::Vector3d co = (origins[0] + origins[1] + origins[2]) / 3.0;
  const double scale = std::sqrt(((points[0] - cx).squaredNorm() + (points[1] - cx).squaredNorm() +
                                  (points[2] - cx).squaredNorm()) / 3.0);
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

  // E13 and E23 as monic quadratics in λ3: λ3² + B λ3 + C.
  const Poly b1 = {-2 * e13.q, -2 * e13.c}, c1 = {e13.r, 2 * e13.p, 1.0};  // in λ1
  const Poly b2 = {-2 * e23.q, -2 * e23.c}, c2 = {e23.r, 2 * e23.p, 1.0};  // in λ2
  const Bi B1 = Bi::InX(b1), C1 = Bi::InX(c1), B2 = Bi::InY(b2), C2 = Bi::InY(c2);
  // Resultant in λ3: (C2 − C1)² + (B2 − B1)[(B2 − B1) C1 − B1 (C2 − C1)].
  const Bi dB = B2 - B1, dC = C2 - C1;
  const Bi f = dC * dC + dB * (dB * C1 - B1 * dC);
  // Reduce f modulo E12 = λ2² + b λ2 + c (b, c in λ1): f ≡ G1 λ2 + G0.
  const Poly b = {-2 * e12.q, -2 * e12.c}, c = {e12.r, 2 * e12.p, 1.0};
  std::array<Poly, 5> g;
  for (int j = 0; j < 5; ++j) {
    g[j].resize(5);
    for (int i = 0; i < 5; ++i) g[j][i] = f.c[i][j];
  }
  for (int j = 4; j >= 2; --j) {
    g[j - 1] = poly::Sub(g[j - 1], poly::Mul(b, g[j]));
    g[j - 2] = poly::Sub(g[j - 2], poly::Mul(c, g[j]));
  }
  const Poly& g0 = g[0];
  const Poly& g1 = g[1];
  const Poly univariate = poly::Add(
      poly::Sub(poly::Mul(g0, g0), poly::Mul(b, poly::Mul(g0, g1))), poly::Mul(c, poly::Mul(g1, g1)));
  std::vector<double> roots1;
  poly::SturmRealRoots(univariate, &roots1);

  std::vector<Eigen::Vector3d> depths;
  for (const double l1 : roots1) {
    double l2s[2];
    int n2;
    const double g1v = poly::Eval(g1, l1);
    if (std::abs(g1v) > 1e-10 * (std::abs(poly::Eval(g0, l1)) + 1e-300)) {
      l2s[0] = -poly::Eval(g0, l1) / g1v;
      n2 = 1;
    } else {
      n2 = Quadratic(poly::Eval(b, l1), poly::Eval(c, l1), l2s);
    }
    for (int k2 = 0; k2 < n2; ++k2) {
      const double l2 = l2s[k2];
      double l3s[2];
      int n3;
      const double den = poly::Eval(b1, l1) - poly::Eval(b2, l2);
      const double num = poly::Eval(c1, l1) - poly::Eval(c2, l2);
      if (std::abs(den) > 1e-10 * (std::abs(num) + 1e-300)) {
        l3s[0] = -num / den;
        n3 = 1;
      } else {
        n3 = Quadratic(poly::Eval(b1, l1), poly::Eval(c1, l1), l3s);
      }
      for (int k3 = 0; k3 < n3; ++k3) {
        Eigen::Vector3d lam(l1, l2, l3s[k3]);
        // Gauss–Newton polish on the three distance equations.
        for (int it = 0; it < 8; ++it) {
          const Eigen::Vector3d res(e12.Eval(lam[0], lam[1]), e13.Eval(lam[0], lam[2]),
                                    e23.Eval(lam[1], lam[2]));
          Eigen::Matrix3d jac;
          jac << e12.DLi(lam[0], lam[1]), e12.DLj(lam[0], lam[1]), 0,
              e13.DLi(lam[0], lam[2]), 0, e13.DLj(lam[0], lam[2]),
              0, e23.DLi(lam[1], lam[2]), e23.DLj(lam[1], lam[2]);
          const Eigen::Vector3d step = jac.partialPivLu().solve(res);
          if (!step.allFinite()) break;
          lam -= step;
          if (step.norm() < 1e-15 * (1.0 + lam.norm())) break;
        }
        const double residual = std::abs(e12.Eval(lam[0], lam[1])) +
                                std::abs(e13.Eval(lam[0], lam[2])) +
                                std::abs(e23.Eval(lam[1], lam[2]));
        if (!(residual < 1e-9) || !lam.allFinite()) continue;
        if (positive_depths && !(lam.array() > 0).all()) continue;
        bool duplicate = false;
        for (const Eigen::Vector3d& other : depths) {
          duplicate |= (other - lam).norm() < 1e-9 * (1 + lam.norm());
        }
        if (!duplicate) depths.push_back(lam);
      }
    }
  }

  for (const Eigen::Vector3d& lam : depths) {
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
