#include "linecloud/solvers/m_p4l_u.h"

#include <array>
#include <cmath>

#include <Eigen/Cholesky>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

using poly::Poly;
using PolyMatrix = std::array<std::array<Poly, 4>, 4>;

Poly Determinant(const PolyMatrix& m, int size, const std::array<int, 4>& rows,
                 const std::array<int, 4>& cols) {
  if (size == 1) return m[rows[0]][cols[0]];
  Poly det;
  std::array<int, 4> sub_rows{};
  for (int i = 1; i < size; ++i) sub_rows[i - 1] = rows[i];
  for (int k = 0; k < size; ++k) {
    std::array<int, 4> sub_cols{};
    for (int j = 0, n = 0; j < size; ++j) {
      if (j != k) sub_cols[n++] = cols[j];
    }
    const Poly term = poly::Mul(m[rows[0]][cols[k]], Determinant(m, size - 1, sub_rows, sub_cols));
    det = (k % 2 == 0) ? poly::Add(det, term) : poly::Sub(det, term);
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
  PolyMatrix pm;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      const double kc = coef[i][0][j] / norm, ks = coef[i][1][j] / norm, k1 = coef[i][2][j] / norm;
      pm[i][j] = {kc + k1, 2 * ks, k1 - kc};
    }
  }
  const Poly det = Determinant(pm, 4, {0, 1, 2, 3}, {0, 1, 2, 3});
  std::vector<double> roots;
  poly::RealRoots(det, &roots);
  for (const double x : roots) {
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
