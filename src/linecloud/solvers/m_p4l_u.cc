#include "linecloud/solvers/m_p4l_u.h"

#include "linecloud/util/check.h"

#include <array>
#include <cmath>

#include <Eigen/Geometry>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

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
std::array<double, 9> Determinant(const std::array<std::array<Quad, 4>, 4>& m) {
  static constexpr int kPairs[6][2] = {{0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}};
  const auto minor = [&](int r0, int r1, int c0, int c1) {
    Quartic a = MulQuad(m[r0][c0], m[r1][c1]);
    const Quartic b = MulQuad(m[r0][c1], m[r1][c0]);
    for (int i = 0; i < 5; ++i) a[i] -= b[i];
    return a;
  };
  std::array<double, 9> det{};
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

int m_p4l_u(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
            std::span<const PluckerLine> lines, std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p4l_u", 4, out, origins, directions, lines);
  out->clear();
  // Per equation: coefficients of c, s, 1 for (t_x, t_y, t_z, constant).
  std::array<std::array<Eigen::Vector4d, 3>, 4> coef;
  double squared_norm = 0;
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
    squared_norm = std::max({squared_norm, coef[i][0].squaredNorm(), coef[i][1].squaredNorm(),
                             coef[i][2].squaredNorm()});
  }
  if (!(squared_norm > 0)) return 0;
  const double inverse_norm = 1 / std::sqrt(squared_norm);
  // Entries times (1 + x²): c → 1 − x², s → 2x, 1 → 1 + x².
  std::array<std::array<Quad, 4>, 4> pm;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double kc = coef[i][0][j] * inverse_norm, ks = coef[i][1][j] * inverse_norm;
      const double k1 = coef[i][2][j] * inverse_norm;
      pm[i][j] = {kc + k1, 2 * ks, k1 - kc};
    }
  }
  const std::array<double, 9> det = Determinant(pm);
  double roots[8];
  const int num_roots = poly::SturmRealRoots(det.data(), 8, roots);
  for (int r = 0; r < num_roots; ++r) {
    const double x = roots[r];
    const double c = (1 - x * x) / (1 + x * x), s = 2 * x / (1 + x * x);
    std::array<Eigen::Vector3d, 4> g;  // row i: g_i · t + k_i = 0
    std::array<double, 4> k;
    for (int i = 0; i < 4; ++i) {
      const Eigen::Vector4d row = c * coef[i][0] + s * coef[i][1] + coef[i][2];
      g[i] = row.head<3>();
      k[i] = row[3];
    }
    // The 4 × 4 system [g | k] is singular at a root: t solves the three
    // rows whose 3 × 3 determinant is largest, by Cramer's rule — with
    // rows (a, b, c), det = g_a · (g_b × g_c) and
    // t = −(k_a g_b × g_c + k_b g_c × g_a + k_c g_a × g_b) / det.
    const Eigen::Vector3d c01 = g[0].cross(g[1]), c02 = g[0].cross(g[2]);
    const Eigen::Vector3d c03 = g[0].cross(g[3]), c12 = g[1].cross(g[2]);
    const Eigen::Vector3d c13 = g[1].cross(g[3]), c23 = g[2].cross(g[3]);
    // Triples (1,2,3), (0,2,3), (0,1,3), (0,1,2); their determinants.
    const std::array<double, 4> dets = {g[1].dot(c23), g[0].dot(c23), g[0].dot(c13), g[0].dot(c12)};
    int drop = 0;
    for (int j = 1; j < 4; ++j) {
      if (std::abs(dets[j]) > std::abs(dets[drop])) drop = j;
    }
    if (!(std::abs(dets[drop]) > 0)) continue;
    Eigen::Vector3d weighted;
    switch (drop) {
      case 0:
        weighted = k[1] * c23 - k[2] * c13 + k[3] * c12;
        break;  // rows 1, 2, 3
      case 1:
        weighted = k[0] * c23 - k[2] * c03 + k[3] * c02;
        break;  // rows 0, 2, 3
      case 2:
        weighted = k[0] * c13 - k[1] * c03 + k[3] * c01;
        break;  // rows 0, 1, 3
      default:
        weighted = k[0] * c12 - k[1] * c02 + k[2] * c01;
        break;  // rows 0, 1, 2
    }
    const Eigen::Vector3d t = -weighted / dets[drop];
    if (!t.allFinite()) continue;
    out->emplace_back(upright::RotationY(c, s), t);
  }
  return static_cast<int>(out->size());
}

int p4l_u(std::span<const Eigen::Vector3d> bearings, std::span<const PluckerLine> lines,
          std::vector<Rigid3d>* out) {
  CheckMinimalSample("p4l_u", 4, out, bearings, lines);
  static const std::array<Eigen::Vector3d, 4> kOrigins = {
      Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
      Eigen::Vector3d::Zero()};
  return m_p4l_u(kOrigins, bearings, lines, out);
}

}  // namespace linecloud
