#include "linecloud/solvers/m_p4l_u.h"

#include <array>
#include <cmath>

#include <Eigen/Cholesky>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

using poly::Poly;

// Quadratic (3 coefficients) and quartic (5) polynomials in x, fixed size.
using Quad = std::array<double, 3>;
using Quartic = std::array<double, 5>;

Quartic MulQuad(const Quad& a, const Quad& b) {
  Quartic r{};
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) r[i + j] += a[i] * b[j];
  return r;
}

// det of a 4 x 4 matrix of quadratics by Laplace expansion along rows (0, 1)
// with complementary 2 x 2 minors of rows (2, 3): a degree-8 polynomial.
Poly Determinant(const std::array<std::array<Quad, 4>, 4>& m) {
  static constexpr int kPairs[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  const auto minor = [&](int r0, int r1, int c0, int c1) {
    Quartic a = MulQuad(m[r0][c0], m[r1][c1]);
    const Quartic b = MulQuad(m[r0][c1], m[r1][c0]);
    for (int i = 0; i < 5; ++i) a[i] -= b[i];
    return a;
  };
  Poly det(9, 0.0);
  for (int k = 0; k < 6; ++k) {
    const int c0 = kPairs[k][0], c1 = kPairs[k][1];
    const int d0 = kPairs[5 - k][0], d1 = kPairs[5 - k][1];  // complement
    // Sign of the permutation (c0, c1, d0, d1) relative to (0, 1, 2, 3).
    const int sign = ((c0 + c1 + 1) % 2 == 0) ? 1 : -1;
    const Quartic top = minor(0, 1, c0, c1), bottom = minor(2, 3, d0, d1);
    for (int i = 0; i < 5; ++i)
      for (int j = 0; j < 5; ++j) det[i + j] += sign * top[i] * bottom[j];
  }
  return det;
}

}  // namespace

int m_p4l_u(std::span<const Eigen::Vector3d> origins,
            std::span<const Eigen::Vector3d> directions,
            std::span<const PluckerLine> lines, std::vector<Rigid3d>* out) {
  out->clear();
  // Per equation: coefficients of c, s, 1 for (t_x, t_y, t_z, constant).
  std::array<std::array<Eigen::Vector4d, 3>, 4> coef;
  double norm = 0;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d& d = directions[i];
    const Eigen::Vector3d m = origins[i].cross(d);
    const Eigen::Vector3d& v = lines[i].v;
    const Eigen::Vector3d& w = lines[i].w;
    if (!d.allFinite() || !m.allFinite() || !v.allFinite() || !w.allFinite()) return 0;
    const Eigen::Vector3d av = upright::A(v), bv = upright::B(v), dv = upright::D(v);
    coef[i][0] << av.cross(d), d.dot(upright::A(w)) + m.dot(av);
    coef[i][1] << bv.cross(d), d.dot(upright::B(w)) + m.dot(bv);
    coef[i][2] << dv.cross(d), d.dot(upright::D(w)) + m.dot(dv);
    norm = std::max({norm, coef[i][0].norm(), coef[i][1].norm(), coef[i][2].norm()});
  }
  if (!(norm > 0)) return 0;
  // Entries times (1 + x²): c → 1 − x², s → 2x, 1 → 1 + x².
  std::array<std::array<Quad, 4>, 4> pm;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double kc = coef[i][0][j] / norm, ks = coef[i][1][j] / norm, k1 = coef[i][2][j] / norm;
      pm[i][j] = {kc + k1, 2 * ks, k1 - kc};
    }
  }
  const Poly det = Determinant(pm);
  double roots[8];
  const int num_roots = poly::SturmRealRoots(det.data(), 8, roots);
  for (int r = 0; r < num_roots; ++r) {
    const double x = roots[r];
    const double c = (1 - x * x) / (1 + x * x), s = 2 * x / (1 + x * x);
    Eigen::Matrix<double, 4, 3> g;
    Eigen::Vector4d k;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector4d row = c * coef[i][0] + s * coef[i][1] + coef[i][2];
      g.row(i) = row.head<3>().transpose();
      k[i] = row[3];
    }
    const Eigen::Matrix3d normal = g.transpose() * g;
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal);
    if (ldlt.info() != Eigen::Success) continue;
    const Eigen::Vector3d t = ldlt.solve(-g.transpose() * k);
    if (!t.allFinite()) continue;
    out->emplace_back(upright::RotationY(c, s), t);
  }
  return static_cast<int>(out->size());
}

int p4l_u(std::span<const Eigen::Vector3d> bearings, std::span<const PluckerLine> lines,
          std::vector<Rigid3d>* out) {
  static const std::array<Eigen::Vector3d, 4> kOrigins = {
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero()};
  return m_p4l_u(kOrigins, bearings, lines, out);
}

}  // namespace linecloud
