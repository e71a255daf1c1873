#include "linecloud/solvers/m_p4l_l.h"

#include "linecloud/util/check.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include <Eigen/Geometry>
#include <Eigen/LU>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

// A 3-vector of scalars for the per-root arithmetic (kept in registers).
using S3 = std::array<double, 3>;
S3 Cross(const S3& a, const S3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
double Dot(const S3& a, const S3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

// Elimination template for three quadrics, action = multiplication by z,
// from tools/elimination_template.py three_quadrics_z. Monomials are exponent
// triples (x, y, z) of degree ≤ 4.
struct Exponent {
  int x, y, z;
};
constexpr int kRows = 26;
constexpr int kCols = 34;
constexpr int kBasis = 8;
constexpr int kReducible = 3;
constexpr int kEliminated = kCols - kBasis - kReducible;  // 23
// Quadric monomials: 1, x, y, z, x², xy, xz, y², yz, z².
constexpr std::array<Exponent, 10> kQuadricMonomials = {{{0, 0, 0},
                                                         {1, 0, 0},
                                                         {0, 1, 0},
                                                         {0, 0, 1},
                                                         {2, 0, 0},
                                                         {1, 1, 0},
                                                         {1, 0, 1},
                                                         {0, 2, 0},
                                                         {0, 1, 1},
                                                         {0, 0, 2}}};
// Basis B = (z³, xz, yz, z², x, y, z, 1); z·B leaves B in z⁴, xz², yz².
constexpr std::array<Exponent, kBasis> kBasisMonomials = {
    {{0, 0, 3}, {1, 0, 1}, {0, 1, 1}, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}}};
constexpr std::array<Exponent, kReducible> kReducibleMonomials = {
    {{0, 0, 4}, {1, 0, 2}, {0, 1, 2}}};
// Rows: (equation, multiplier).
struct Row {
  int equation;
  Exponent multiplier;
};
constexpr std::array<Row, kRows> kTemplateRows = {
    {{0, {0, 0, 0}}, {0, {0, 0, 1}}, {0, {0, 1, 0}}, {0, {1, 0, 0}}, {0, {0, 0, 2}}, {0, {0, 1, 1}},
     {0, {0, 2, 0}}, {0, {1, 0, 1}}, {1, {0, 0, 0}}, {1, {0, 0, 1}}, {1, {0, 1, 0}}, {1, {1, 0, 0}},
     {1, {0, 0, 2}}, {1, {0, 1, 1}}, {1, {0, 2, 0}}, {1, {1, 0, 1}}, {1, {1, 1, 0}}, {2, {0, 0, 0}},
     {2, {0, 0, 1}}, {2, {0, 1, 0}}, {2, {1, 0, 0}}, {2, {0, 0, 2}}, {2, {0, 1, 1}}, {2, {0, 2, 0}},
     {2, {1, 0, 1}}, {2, {1, 1, 0}}}};

// column[r][k]: template column of quadric monomial k multiplied by row r's
// multiplier; columns are ordered eliminated | reducible | basis.
struct TemplateLayout {
  std::array<std::array<int, 10>, kRows> column;
};

TemplateLayout MakeLayout() {
  constexpr int kUnset = -1;
  std::array<int, 125> index;  // (x, y, z) → column, exponents < 5
  index.fill(kUnset);
  const auto key = [](Exponent e) { return (e.x * 5 + e.y) * 5 + e.z; };
  for (int i = 0; i < kReducible; ++i) index[key(kReducibleMonomials[i])] = kEliminated + i;
  for (int i = 0; i < kBasis; ++i) {
    index[key(kBasisMonomials[i])] = kEliminated + kReducible + i;
  }
  int next = 0;
  TemplateLayout layout{};
  for (int r = 0; r < kRows; ++r) {
    for (int k = 0; k < 10; ++k) {
      const Exponent m = kTemplateRows[r].multiplier;
      const Exponent q = kQuadricMonomials[k];
      const int c = key({m.x + q.x, m.y + q.y, m.z + q.z});
      if (index[c] == kUnset) index[c] = next++;
      layout.column[r][k] = index[c];
    }
  }
  return layout;  // next == kEliminated for a consistent template
}

const TemplateLayout& Layout() {
  static const TemplateLayout layout = MakeLayout();
  return layout;
}

// Coefficient vectors of M(q) X̃ on the monomials (ww, wx, wy, wz, xx, xy,
// xz, yy, yz, zz) of q = (w, x, y, z), where M(q) = |q|² R(q / |q|).
Eigen::Matrix<double, 3, 10> RotateCoefficients(const Eigen::Vector3d& p) {
  const double a = p.x(), b = p.y(), c = p.z();
  Eigen::Matrix<double, 3, 10> m;
  m.col(0) << a, b, c;
  m.col(1) << 0, -2 * c, 2 * b;
  m.col(2) << 2 * c, 0, -2 * a;
  m.col(3) << -2 * b, 2 * a, 0;
  m.col(4) << a, -b, -c;
  m.col(5) << 2 * b, 2 * a, 0;
  m.col(6) << 2 * c, 0, 2 * a;
  m.col(7) << -a, b, -c;
  m.col(8) << 0, 2 * c, 2 * b;
  m.col(9) << -a, -b, c;
  return m;
}

Eigen::Matrix<double, 10, 1> QuaternionMonomials(const Eigen::Vector4d& q) {
  Eigen::Matrix<double, 10, 1> m;
  m << q[0] * q[0], q[0] * q[1], q[0] * q[2], q[0] * q[3], q[1] * q[1], q[1] * q[2], q[1] * q[3],
      q[2] * q[2], q[2] * q[3], q[3] * q[3];
  return m;
}

// A fixed generic rotation applied to the local points before solving, so that
// the dehomogenisation q_w = 1 misses structured poses (e.g. 180° yaw).
const Eigen::Quaterniond& PreRotationQuaternion() {
  static const Eigen::Quaterniond q =
      Eigen::Quaterniond(0.8273, 0.3185, -0.2417, 0.3944).normalized();
  return q;
}
const Eigen::Matrix3d& PreRotation() {
  static const Eigen::Matrix3d r = PreRotationQuaternion().toRotationMatrix();
  return r;
}

// Polynomials in z, coefficients from the constant term up.
template <size_t N>
using ZPoly = std::array<double, N>;

template <size_t A, size_t B>
ZPoly<A + B - 1> Multiply(const ZPoly<A>& a, const ZPoly<B>& b) {
  ZPoly<A + B - 1> c{};
  for (size_t i = 0; i < A; ++i) {
    for (size_t j = 0; j < B; ++j) c[i + j] += a[i] * b[j];
  }
  return c;
}

// c += s · a (a no longer than c).
template <size_t A, size_t C>
void AddScaled(const ZPoly<A>& a, double s, ZPoly<C>* c) {
  static_assert(A <= C);
  for (size_t i = 0; i < A; ++i) (*c)[i] += s * a[i];
}

// Three relations X_b(z) x + Y_b(z) y + C_b(z) = 0 (b = 0, 1, 2) that every
// intersection satisfies; det[X Y C] is then a polynomial of degree 8 in z
// whose roots are the intersections' z (Bézout: 2·2·2).
struct HiddenZRelations {
  std::array<ZPoly<4>, 3> x, y;
  std::array<ZPoly<5>, 3> c;
};

// The relations with z as the hidden variable (the idea of Kukelova, Heller,
// Bujnak, Fitzgibbon, Pajdla, "Efficient intersection of three quadrics and
// applications in computer vision", CVPR 2016):
//   1. The quadrics are linear in (x², xy, y²) with the rest on
//      (1, x, y, z, xz, yz, z²): solved, x² = A₁, xy = A₂, y² = A₃ with
//      Aᵢ = αᵢ(z) x + βᵢ(z) y + γᵢ(z), α, β linear and γ quadratic in z.
//   2. x·xy = y·x² and x·y² = y·xy, rewritten by step 1:
//      S₁ = x A₂ − y A₁ = α₂A₁ + (β₂ − α₁)A₂ − β₁A₃ + γ₂x − γ₁y = 0,
//      S₂ = x A₃ − y A₂ = α₃A₁ + (β₃ − α₂)A₂ − β₂A₃ + γ₃x − γ₂y = 0,
//      both linear in (x, y): degrees (2, 2, 3) in z.
//   3. x·S₂ = X₁A₁ + Y₁A₂ + C₁x = 0, degrees (3, 3, 4). (x·S₁ would not do:
//      it lies in the span of S₁ and S₂ over k(z) — measured, det ≡ 0.)
// det[S₁; S₂; x·S₂] has degree 2 + 2 + 4 = 8, the action matrix's
// characteristic polynomial up to a constant factor. False when step 1's
// 3 × 3 system is ill-conditioned (IntersectThreeQuadrics then retries in
// rotated variables, then takes the elimination template).
bool HiddenZ(const Eigen::Matrix<double, 3, 10>& quadrics, HiddenZRelations* out) {
  // Quadric columns: 1, x, y, z, x², xy, xz, y², yz, z².
  Eigen::Matrix3d leading;
  leading << quadrics.col(4), quadrics.col(5), quadrics.col(7);
  const double det = leading.determinant();
  const double hadamard = leading.row(0).norm() * leading.row(1).norm() * leading.row(2).norm();
  if (!(std::abs(det) > 1e-6 * hadamard)) return false;
  const Eigen::Matrix3d inverse = leading.inverse();
  // Aᵢ = −(leading⁻¹ · rest)ᵢ on the rest's columns.
  const auto rest = [&](int i, int column) { return -inverse.row(i).dot(quadrics.col(column)); };
  std::array<ZPoly<2>, 3> alpha, beta;
  std::array<ZPoly<3>, 3> gamma;
  for (int i = 0; i < 3; ++i) {
    alpha[i] = {rest(i, 1), rest(i, 6)};              // x, xz
    beta[i] = {rest(i, 2), rest(i, 8)};               // y, yz
    gamma[i] = {rest(i, 0), rest(i, 3), rest(i, 9)};  // 1, z, z²
  }
  // The relation Σ cᵢAᵢ + dx·x + dy·y as (X, Y, C) = (Σ cᵢαᵢ + dx, Σ cᵢβᵢ + dy,
  // Σ cᵢγᵢ), written to slot b.
  const auto relation = [&](int b, const auto& c, const ZPoly<4>& dx, const ZPoly<4>& dy) {
    out->x[b] = dx;
    out->y[b] = dy;
    out->c[b] = {};
    for (int i = 0; i < 3; ++i) {
      AddScaled(Multiply(c[i], alpha[i]), 1, &out->x[b]);
      AddScaled(Multiply(c[i], beta[i]), 1, &out->y[b]);
      AddScaled(Multiply(c[i], gamma[i]), 1, &out->c[b]);
    }
  };
  const auto pad = [](const auto& p) {
    ZPoly<4> padded{};
    for (size_t i = 0; i < std::min<size_t>(p.size(), 4); ++i) padded[i] = p[i];
    return padded;
  };
  for (int k = 0; k < 2; ++k) {
    // k = 0: S₁ (c = α₂, β₂ − α₁, −β₁; dx = γ₂, dy = −γ₁); k = 1: S₂ (indices + 1).
    const std::array<ZPoly<2>, 3> c = {
        alpha[k + 1], ZPoly<2>{beta[k + 1][0] - alpha[k][0], beta[k + 1][1] - alpha[k][1]},
        ZPoly<2>{-beta[k][0], -beta[k][1]}};
    const ZPoly<3> minus_gamma = {-gamma[k][0], -gamma[k][1], -gamma[k][2]};
    relation(k, c, pad(gamma[k + 1]), pad(minus_gamma));
  }
  // x·S₂: c = (X₁, Y₁, 0), dx = C₁ (S₂'s degrees are 2, 2 and 3, so the
  // padding drops only zeros).
  const std::array<ZPoly<3>, 3> c = {ZPoly<3>{out->x[1][0], out->x[1][1], out->x[1][2]},
                                     ZPoly<3>{out->y[1][0], out->y[1][1], out->y[1][2]},
                                     ZPoly<3>{}};
  relation(2, c, pad(out->c[1]), ZPoly<4>{});
  return true;
}

// Newton steps on the three quadrics (until the step is negligible, at most
// 4): the eigenvectors of the action matrix carry its conditioning; Newton
// restores full precision.
void PolishRoot(const Eigen::Matrix<double, 3, 10>& quadrics, Eigen::Vector3d* xyz) {
  // Scalar 3-vectors (S3): Eigen temporaries filled entry by entry and read
  // back as packets stalled on store forwarding here.
  double x = xyz->x(), y = xyz->y(), z = xyz->z();
  for (int iteration = 0; iteration < 4; ++iteration) {
    // Columns: 1, x, y, z, x², xy, xz, y², yz, z². Row i: f_i and ∂f_i.
    S3 f, jx, jy, jz;
    for (int i = 0; i < 3; ++i) {
      const auto q = quadrics.row(i);
      f[i] = q[0] + (q[1] + q[4] * x + q[5] * y + q[6] * z) * x + (q[2] + q[7] * y + q[8] * z) * y +
             (q[3] + q[9] * z) * z;
      jx[i] = q[1] + 2 * q[4] * x + q[5] * y + q[6] * z;
      jy[i] = q[2] + q[5] * x + 2 * q[7] * y + q[8] * z;
      jz[i] = q[3] + q[6] * x + q[8] * y + 2 * q[9] * z;
    }
    // Cramer's rule: J⁻¹ f = adj(J) f / det J, with adj(J)'s rows the cross
    // products of J's columns.
    const S3 r0 = Cross(jy, jz);
    const double inv_det = 1 / Dot(jx, r0);
    const double sx = Dot(r0, f) * inv_det, sy = Dot(Cross(jz, jx), f) * inv_det,
                 sz = Dot(Cross(jx, jy), f) * inv_det;
    if (!std::isfinite(sx + sy + sz)) break;
    x -= sx, y -= sy, z -= sz;
    // Newton converges quadratically: after a step of relative size δ the
    // error is O(δ²), so a step below 1e-7 leaves ~1e-14 and ends the loop.
    const double size = std::max(1.0, x * x + y * y + z * z);
    if (sx * sx + sy * sy + sz * sz < 1e-14 * size) break;
  }
  *xyz = Eigen::Vector3d(x, y, z);
}

// The action of z from the 26 × 34 elimination template (Gaussian elimination
// with partial pivoting): the last fallback, for quadrics whose (x², xy, y²)
// block is too ill-conditioned for HiddenZ's step 1 even after a rotation of
// the variables (none of 10 000 random m-P4L+l instances needs either).
bool TemplateActionRows(const Eigen::Matrix<double, 3, 10>& quadrics, double rows[3][8]) {
  const TemplateLayout& layout = Layout();
  // Row-major template; Gaussian elimination with partial pivoting on its
  // first kRows columns (in place, on the whole rows), then back substitution
  // for the last kReducible unknowns only: the reducible monomials are
  // −(T_sq⁻¹ T_B)[reducible rows] · basis, and an upper-triangular system
  // gives its last rows from its trailing block alone.
  double t[kRows][kCols] = {};
  for (int r = 0; r < kRows; ++r) {
    for (int k = 0; k < 10; ++k) {
      t[r][layout.column[r][k]] = quadrics(kTemplateRows[r].equation, k);
    }
  }
  const double scale = quadrics.cwiseAbs().maxCoeff();
  for (int k = 0; k < kRows; ++k) {
    int pivot = k;
    for (int r = k + 1; r < kRows; ++r) {
      if (std::abs(t[r][k]) > std::abs(t[pivot][k])) pivot = r;
    }
    if (!(std::abs(t[pivot][k]) > 1e-14 * scale)) return false;  // singular template
    if (pivot != k) std::swap(t[pivot], t[k]);
    const double inverse = 1.0 / t[k][k];
    for (int r = k + 1; r < kRows; ++r) {
      const double factor = t[r][k] * inverse;
      if (factor == 0) continue;
      for (int c = k + 1; c < kCols; ++c) t[r][c] -= factor * t[k][c];
    }
  }
  for (int j = 0; j < kBasis; ++j) {
    double x[kReducible];
    for (int i = kReducible - 1; i >= 0; --i) {
      const int r = kEliminated + i;
      double v = t[r][kRows + j];
      for (int c = i + 1; c < kReducible; ++c) v -= t[r][kEliminated + c] * x[c];
      x[i] = v / t[r][r];
    }
    for (int i = 0; i < kReducible; ++i) rows[i][j] = -x[i];
  }
  return true;
}

// The quadrics in p' for p = M p': with q(p) = c + gᵀp + pᵀHp, the new
// coefficients are c, Mᵀg and MᵀHM (columns 1, x, y, z, x², xy, xz, y², yz, z²).
Eigen::Matrix<double, 3, 10> ChangeVariables(const Eigen::Matrix<double, 3, 10>& quadrics,
                                             const Eigen::Matrix3d& m) {
  Eigen::Matrix<double, 3, 10> out;
  for (int i = 0; i < 3; ++i) {
    const auto q = quadrics.row(i);
    Eigen::Matrix3d h;
    h << q[4], q[5] / 2, q[6] / 2, q[5] / 2, q[7], q[8] / 2, q[6] / 2, q[8] / 2, q[9];
    const Eigen::Vector3d g = m.transpose() * Eigen::Vector3d(q[1], q[2], q[3]);
    const Eigen::Matrix3d hm = m.transpose() * h * m;
    out.row(i) << q[0], g.x(), g.y(), g.z(), hm(0, 0), 2 * hm(0, 1), 2 * hm(0, 2), hm(1, 1),
        2 * hm(1, 2), hm(2, 2);
  }
  return out;
}

// A fixed generic rotation for ChangeVariables.
const Eigen::Matrix3d& FallbackRotation() {
  static const Eigen::Matrix3d r =
      Eigen::Quaterniond(0.6124, -0.3536, 0.5303, 0.4677).normalized().toRotationMatrix();
  return r;
}

}  // namespace

int IntersectThreeQuadrics(const Eigen::Matrix<double, 3, 10>& quadrics,
                           std::vector<Eigen::Vector3d>* out) {
  out->clear();
  if (!quadrics.allFinite()) return 0;
  if (!(quadrics.cwiseAbs().maxCoeff() > 0)) return 0;
  HiddenZRelations rel;
  // A (x², xy, y²) block that is singular in these coordinates (a quadric
  // without those terms, say) is usually regular after a generic rotation of
  // (x, y, z): HiddenZ then solves for p' with p = M p'.
  bool rotated = false;
  if (!HiddenZ(quadrics, &rel)) {
    rotated = HiddenZ(ChangeVariables(quadrics, FallbackRotation()), &rel);
    if (!rotated) {
      // The elimination template gives the action of z (multiplication by z
      // on the basis β = (z³, xz, yz, z², x, y, z, 1)); its three rows that
      // are not unit rows (the normal forms of z⁴, xz², yz²) say
      // z·β = action·β, i.e. three relations linear in (x, y) for fixed z
      // whose determinant is the action's characteristic polynomial.
      double action[3][8];
      if (!TemplateActionRows(quadrics, action)) return 0;
      for (int b = 0; b < 3; ++b) {
        rel.x[b] = {action[b][4], action[b][1], b == 1 ? -1.0 : 0.0, 0.0};
        rel.y[b] = {action[b][5], action[b][2], b == 2 ? -1.0 : 0.0, 0.0};
        rel.c[b] = {action[b][7], action[b][6], action[b][3], action[b][0], b == 0 ? -1.0 : 0.0};
      }
    }
  }
  // z is a root of det[X Y C] (degree 8), real roots by Sturm sequences (no
  // eigen-decomposition); (x, y) then from the 3 × 2 linear system.
  // Minors Y_i C_j − Y_j C_i, then the expansion along the X column; the
  // degrees of the relations keep the products beyond z⁸ exactly zero.
  const auto minor = [&](int i, int j) {
    ZPoly<8> m = Multiply(rel.y[i], rel.c[j]);
    AddScaled(Multiply(rel.y[j], rel.c[i]), -1, &m);
    return m;
  };
  const std::array<ZPoly<8>, 3> minors = {minor(1, 2), minor(0, 2), minor(0, 1)};
  ZPoly<11> det{};
  for (int b = 0; b < 3; ++b) {
    AddScaled(Multiply(rel.x[b], minors[b]), b == 1 ? -1.0 : 1.0, &det);
  }
  for (double v : det) {
    if (!std::isfinite(v)) return 0;
  }
  double z_roots[8];
  const int num_roots = poly::SturmRealRoots(det.data(), 8, z_roots);
  for (int k = 0; k < num_roots; ++k) {
    const double z = z_roots[k];
    S3 m0, m1, rhs;
    for (int b = 0; b < 3; ++b) {
      const ZPoly<4>& x = rel.x[b];
      const ZPoly<4>& y = rel.y[b];
      const ZPoly<5>& c = rel.c[b];
      m0[b] = ((x[3] * z + x[2]) * z + x[1]) * z + x[0];
      m1[b] = ((y[3] * z + y[2]) * z + y[1]) * z + y[0];
      rhs[b] = -((((c[4] * z + c[3]) * z + c[2]) * z + c[1]) * z + c[0]);
    }
    // (x, y) from the consistent 3 × 2 system [m₀ m₁] (x, y)ᵀ = rhs: with n the
    // cross product of the columns, x = (rhs × m₁)·n / |n|², y = (m₀ × rhs)·n
    // / |n|² (exact when rhs lies in their span, the least-squares solution
    // otherwise). Rank < 2: (x, y) not determined by this root (a solution at
    // infinity or a degenerate configuration).
    const S3 n = Cross(m0, m1);
    const double n2 = Dot(n, n);
    if (!(n2 > 1e-24 * Dot(m0, m0) * Dot(m1, m1))) continue;
    const double inv_n2 = 1 / n2;
    const Eigen::Vector2d xy(Dot(Cross(rhs, m1), n) * inv_n2, Dot(Cross(m0, rhs), n) * inv_n2);
    Eigen::Vector3d xyz(xy.x(), xy.y(), z);
    if (rotated) xyz = FallbackRotation() * xyz;
    PolishRoot(quadrics, &xyz);
    if (xyz.allFinite()) out->push_back(xyz);
  }
  return static_cast<int>(out->size());
}

int m_p4l_l(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
            std::vector<Sim3d>* out) {
  CheckMinimalSample("m_p4l_l", 4, out, lines, points_local);
  out->clear();
  // Normalise both sides: centroid at the origin, unit RMS radius.
  Eigen::Vector3d mean_local = Eigen::Vector3d::Zero(), mean_world = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, 4> anchors;
  for (int i = 0; i < 4; ++i) {
    if (!points_local[i].allFinite() || !lines[i].v.allFinite() || !lines[i].w.allFinite() ||
        !(lines[i].v.squaredNorm() > 0)) {
      return 0;
    }
    anchors[i] = lines[i].Anchor() / lines[i].v.squaredNorm();
    mean_local += points_local[i] / 4;
    mean_world += anchors[i] / 4;
  }
  double spread_local = 0, spread_world = 0;
  for (int i = 0; i < 4; ++i) {
    spread_local += (points_local[i] - mean_local).squaredNorm() / 4;
    spread_world += (anchors[i] - mean_world).squaredNorm() / 4;
  }
  spread_local = std::sqrt(spread_local);
  spread_world = std::sqrt(spread_world);
  if (!(spread_local > 0)) return 0;  // all local points coincide
  if (!(spread_world > 0)) spread_world = 1;

  // Rows: u ⟂ v_i; A m + U t' = b with m the quaternion monomials. Row
  // order: the two rows of line i, then for line j the direction of v_i
  // across v_j and its complement, then lines k and l; (i, j) is the least
  // parallel pair, so the first three rows fix t' as well as any three can
  // (|det| = |v_i × v_j|). Rows 3–6 give the quadrics, row 7 the check.
  int pair_i = 0, pair_j = 1;
  double best_sine2 = -1;
  std::array<Eigen::Vector3d, 4> directions;
  for (int i = 0; i < 4; ++i) directions[i] = lines[i].v.normalized();
  for (int i = 0; i < 4; ++i) {
    for (int j = i + 1; j < 4; ++j) {
      const double sine2 = directions[i].cross(directions[j]).squaredNorm();
      if (sine2 > best_sine2) best_sine2 = sine2, pair_i = i, pair_j = j;
    }
  }
  if (!(best_sine2 > 1e-20)) return 0;  // all lines (nearly) parallel
  std::array<int, 4> order = {pair_i, pair_j, 0, 0};
  for (int i = 0, next = 2; i < 4; ++i) {
    if (i != pair_i && i != pair_j) order[next++] = i;
  }
  constexpr int kEq = 8;
  Eigen::Matrix<double, kEq, 10> a;
  Eigen::Matrix<double, kEq, 3> u;
  Eigen::Matrix<double, kEq, 1> b;
  for (int slot = 0; slot < 4; ++slot) {
    const int i = order[slot];
    const Eigen::Vector3d p =
        PreRotation().transpose() * ((points_local[i] - mean_local) / spread_local);
    const Eigen::Matrix<double, 3, 10> coeffs = RotateCoefficients(p);
    const Eigen::Vector3d anchor = (anchors[i] - mean_world) / spread_world;
    Eigen::Vector3d basis[2];
    if (slot == 1) {
      const Eigen::Vector3d& vi = directions[pair_i];
      const Eigen::Vector3d& vj = directions[pair_j];
      basis[0] = (vi - vi.dot(vj) * vj).normalized();
      basis[1] = vj.cross(basis[0]);
    } else {
      upright::OrthogonalBasis(directions[i], &basis[0], &basis[1]);
    }
    for (int k = 0; k < 2; ++k) {
      a.row(2 * slot + k) = basis[k].transpose() * coeffs;
      u.row(2 * slot + k) = basis[k].transpose();
      b[2 * slot + k] = basis[k].dot(anchor);
    }
  }
  // t' = U₃⁻¹ (b₃ − A₃ m) from rows 0–2 (U₃⁻¹'s columns: cross products of
  // its rows over det); row r then reads (A_r − w_rᵀA₃) m = b_r − w_r·b₃ with
  // w_r = U₃⁻ᵀ u_r.
  const Eigen::Vector3d r0 = u.row(0), r1 = u.row(1), r2 = u.row(2);
  Eigen::Matrix3d u3_inverse;
  u3_inverse << r1.cross(r2), r2.cross(r0), r0.cross(r1);
  u3_inverse /= r0.dot(r1.cross(r2));
  const Eigen::Matrix<double, 3, 10> a3 = a.topRows<3>();
  const Eigen::Vector3d b3 = b.head<3>();
  Eigen::Matrix<double, 4, 10> g;
  Eigen::Vector4d h;
  for (int r = 0; r < 4; ++r) {
    const Eigen::Vector3d w = u3_inverse.transpose() * u.row(3 + r).transpose();
    g.row(r) = a.row(3 + r) - w.transpose() * a3;
    h[r] = b[3 + r] - w.dot(b3);
  }
  Eigen::Index pivot;
  const double h_max = h.cwiseAbs().maxCoeff(&pivot);
  // h = 0: the lines meet in one point, where every scale-0 "pose" fits.
  if (!(h_max > 1e-10 * std::max(1.0, g.cwiseAbs().maxCoeff()))) return 0;
  Eigen::Matrix<double, 3, 10> quadrics;
  for (int j = 0, row = 0; j < 4; ++j) {
    if (j == pivot) continue;
    quadrics.row(row++) = g.row(j) * h[pivot] - g.row(pivot) * h[j];
  }
  // Monomials with q_w = 1 are (1, x, y, z, x², xy, xz, y², yz, z²): the same
  // order as (ww, wx, wy, wz, xx, xy, xz, yy, yz, zz).
  thread_local std::vector<Eigen::Vector3d> roots;
  IntersectThreeQuadrics(quadrics, &roots);

  // Every real root with s > 0 is a candidate, ranked by the residual of the
  // eighth equation; the pose is built only for those kept.
  struct Candidate {
    double residual;
    Eigen::Vector4d q;       // M' = Q(q), s' = |q|²
    Eigen::Vector3d t_norm;  // t'
  };
  std::array<Candidate, 8> candidates;
  int count = 0;
  for (const Eigen::Vector3d& xyz : roots) {
    Eigen::Vector4d q(1.0, xyz.x(), xyz.y(), xyz.z());
    const double g_pivot = g.row(pivot).dot(QuaternionMonomials(q));
    const double lambda2 = h[pivot] / g_pivot;
    if (!(lambda2 > 0) || !std::isfinite(lambda2)) continue;
    q *= std::sqrt(lambda2);
    const Eigen::Matrix<double, 10, 1> mono = QuaternionMonomials(q);
    const Eigen::Vector3d t_norm = u3_inverse * (b3 - a3 * mono);
    const double residual =
        std::abs(a.row(kEq - 1).dot(mono) + u.row(kEq - 1).dot(t_norm) - b[kEq - 1]);
    if (!std::isfinite(residual) || count == 8) continue;
    candidates[count++] = {residual, q, t_norm};
  }
  // Insertion sort: at most 8 candidates.
  for (int i = 1; i < count; ++i) {
    for (int j = i; j > 0 && candidates[j].residual < candidates[j - 1].residual; --j) {
      std::swap(candidates[j], candidates[j - 1]);
    }
  }
  // Keep the solutions that also fit the eighth equation: with exact data
  // exactly the solutions of all eight; with noisy data those within 100× of
  // the best fit (normalised units).
  for (int i = 0; i < count; ++i) {
    const Candidate& c = candidates[i];
    if (c.residual > std::max(1e-9, 100 * candidates[0].residual)) break;
    // Undo the normalisation: world = σ_w (M' Pᵀ (X̃ − μ_l) / σ_l + t') + μ_w.
    const Eigen::Quaterniond rotation =
        Eigen::Quaterniond(c.q[0], c.q[1], c.q[2], c.q[3]).normalized() *
        PreRotationQuaternion().conjugate();
    const double scale = c.q.squaredNorm() * spread_world / spread_local;
    const Eigen::Vector3d translation =
        spread_world * c.t_norm + mean_world - scale * (rotation * mean_local);
    if (!std::isfinite(scale) || !translation.allFinite()) continue;
    out->push_back(Sim3d(scale, rotation, translation).Inverse());
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
