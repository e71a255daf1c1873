#include "linecloud/solvers/m_p4l_l.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/QR>

#include "linecloud/solvers/polynomial.h"
#include "linecloud/solvers/upright.h"

namespace linecloud {
namespace {

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
constexpr std::array<Exponent, 10> kQuadricMonomials = {{
    {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {2, 0, 0},
    {1, 1, 0}, {1, 0, 1}, {0, 2, 0}, {0, 1, 1}, {0, 0, 2}}};
// Basis B = (z³, xz, yz, z², x, y, z, 1); z·B leaves B in z⁴, xz², yz².
constexpr std::array<Exponent, kBasis> kBasisMonomials = {{
    {0, 0, 3}, {1, 0, 1}, {0, 1, 1}, {0, 0, 2}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {0, 0, 0}}};
constexpr std::array<Exponent, kReducible> kReducibleMonomials = {{
    {0, 0, 4}, {1, 0, 2}, {0, 1, 2}}};
// Rows: (equation, multiplier).
struct Row {
  int equation;
  Exponent multiplier;
};
constexpr std::array<Row, kRows> kTemplateRows = {{
    {0, {0, 0, 0}}, {0, {0, 0, 1}}, {0, {0, 1, 0}}, {0, {1, 0, 0}}, {0, {0, 0, 2}},
    {0, {0, 1, 1}}, {0, {0, 2, 0}}, {0, {1, 0, 1}},
    {1, {0, 0, 0}}, {1, {0, 0, 1}}, {1, {0, 1, 0}}, {1, {1, 0, 0}}, {1, {0, 0, 2}},
    {1, {0, 1, 1}}, {1, {0, 2, 0}}, {1, {1, 0, 1}}, {1, {1, 1, 0}},
    {2, {0, 0, 0}}, {2, {0, 0, 1}}, {2, {0, 1, 0}}, {2, {1, 0, 0}}, {2, {0, 0, 2}},
    {2, {0, 1, 1}}, {2, {0, 2, 0}}, {2, {1, 0, 1}}, {2, {1, 1, 0}}}};

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
  m << q[0] * q[0], q[0] * q[1], q[0] * q[2], q[0] * q[3], q[1] * q[1], q[1] * q[2],
      q[1] * q[3], q[2] * q[2], q[2] * q[3], q[3] * q[3];
  return m;
}

// A fixed generic rotation applied to the local points before solving, so that
// the dehomogenisation q_w = 1 misses structured poses (e.g. 180° yaw).
const Eigen::Matrix3d& PreRotation() {
  static const Eigen::Matrix3d r =
      Eigen::Quaterniond(0.8273, 0.3185, -0.2417, 0.3944).normalized().toRotationMatrix();
  return r;
}

// Normal forms modulo three quadrics, by hand-derived reduction rules instead
// of the elimination template (the same Gröbner basis, graded reverse
// lexicographic order x > y > z, whose leading monomials are x², xy, y², xz²,
// yz², z⁴ and whose standard monomials are the basis β):
//   1. Solving the quadrics for x², xy, y² gives x² ≡ A₁, xy ≡ A₂, y² ≡ A₃
//      with Aᵢ on the standard monomials (1, x, y, z, xz, yz, z²).
//   2. x·A₂ − y·A₁ and x·A₃ − y·A₂ (the S-polynomials y·q₁ − x·q₂ and
//      x·q₃ − y·q₂, reduced by step 1) are two relations on (xz², yz², z³,
//      xz, yz, z², x, y, z, 1); solved for xz² and yz².
//   3. The S-pairs (x², xz²) and (y², yz²), reduced by steps 1–2, are
//      relations between z⁴ and β (the better-conditioned one is used).
// The three rows of the action of z that are not unit rows are the normal
// forms of z·z³ = z⁴, z·xz = xz², z·yz = yz². Each step solves a small
// linear system (3 × 3, 2 × 2, 1 × 1); false when one of them is singular.
namespace normal_form {

// Monomials x^a y^b z^c of degree ≤ 4.
constexpr int kCount = 35;
struct Table {
  int index[5][5][5];
  int a[kCount], b[kCount], c[kCount];
  // Reduction order: total degree descending, then a + b descending. Every
  // rule rewrites a monomial into monomials later in this order, so one pass
  // reaches the normal form.
  int order[kCount];
};

const Table& Monomials() {
  static const Table table = [] {
    Table t{};
    int next = 0;
    for (int d = 0; d <= 4; ++d) {
      for (int a = d; a >= 0; --a) {
        for (int b = d - a; b >= 0; --b) {
          const int c = d - a - b;
          t.index[a][b][c] = next;
          t.a[next] = a;
          t.b[next] = b;
          t.c[next] = c;
          ++next;
        }
      }
    }
    std::array<int, kCount> order;
    for (int i = 0; i < kCount; ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(), [&](int i, int j) {
      const int di = t.a[i] + t.b[i] + t.c[i], dj = t.a[j] + t.b[j] + t.c[j];
      if (di != dj) return di > dj;
      return t.a[i] + t.b[i] > t.a[j] + t.b[j];
    });
    std::copy(order.begin(), order.end(), t.order);
    return t;
  }();
  return table;
}

using Poly = std::array<double, kCount>;

int Index(int a, int b, int c) { return Monomials().index[a][b][c]; }

// The supports of the rules: Aᵢ on (1, x, y, z, xz, yz, z²), Eᵢ on β.
constexpr std::array<Exponent, 7> kQuadricRest = {{
    {0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 0, 1}, {0, 1, 1}, {0, 0, 2}}};
struct Rule {
  const Exponent* support;
  int size;
  double coefficient[kBasis];
};

// out += factor · x^da y^db z^dc · rule (degrees stay ≤ 4 by construction).
void AddShifted(const Rule& rule, int da, int db, int dc, double factor, Poly* out) {
  const Table& t = Monomials();
  for (int j = 0; j < rule.size; ++j) {
    const Exponent e = rule.support[j];
    (*out)[t.index[e.x + da][e.y + db][e.z + dc]] += factor * rule.coefficient[j];
  }
}

struct Rules {
  Rule a[3];  // x², xy, y² ≡ A₁, A₂, A₃
  Rule e[2];  // xz², yz² ≡ E₁, E₂
  bool with_e = false;
};

// One pass in reduction order, rewriting every monomial a known rule applies to.
void Reduce(const Rules& rules, Poly* p) {
  const Table& t = Monomials();
  for (int k = 0; k < kCount; ++k) {
    const int m = t.order[k];
    const double coefficient = (*p)[m];
    if (coefficient == 0) continue;
    const int a = t.a[m], b = t.b[m], c = t.c[m];
    const Rule* rule = nullptr;
    int da = 0, db = 0, dc = 0;
    if (a >= 2) {
      rule = &rules.a[0], da = a - 2, db = b, dc = c;
    } else if (a >= 1 && b >= 1) {
      rule = &rules.a[1], da = a - 1, db = b - 1, dc = c;
    } else if (b >= 2) {
      rule = &rules.a[2], da = a, db = b - 2, dc = c;
    } else if (rules.with_e && a + b == 1 && c >= 2) {
      rule = &rules.e[a == 1 ? 0 : 1], dc = c - 2;
    }
    if (rule == nullptr) continue;
    (*p)[m] = 0;
    AddShifted(*rule, da, db, dc, coefficient, p);
  }
}

double MaxAbs(const Poly& p) {
  double largest = 0;
  for (double v : p) largest = std::max(largest, std::abs(v));
  return largest;
}

// The action rows for the basis β = (z³, xz, yz, z², x, y, z, 1).
bool ActionRows(const Eigen::Matrix<double, 3, 10>& quadrics, double rows[3][8]) {
  // Quadric columns: 1, x, y, z, x², xy, xz, y², yz, z².
  constexpr int kLeading[3] = {4, 5, 7};
  constexpr int kRest[7] = {0, 1, 2, 3, 6, 8, 9};
  Eigen::Matrix3d leading;
  Eigen::Matrix<double, 3, 7> rest;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) leading(i, j) = quadrics(i, kLeading[j]);
    for (int j = 0; j < 7; ++j) rest(i, j) = quadrics(i, kRest[j]);
  }
  // Step 1: leading · (x², xy, y²) + rest · (…) = 0. The thresholds of the
  // three steps send the ~0.1 % worst-conditioned instances to the template.
  const double det = leading.determinant();
  const double hadamard =
      leading.row(0).norm() * leading.row(1).norm() * leading.row(2).norm();
  if (!(std::abs(det) > 1e-6 * hadamard)) return false;
  const Eigen::Matrix<double, 3, 7> solved = -(leading.inverse() * rest);
  Rules rules;
  for (int i = 0; i < 3; ++i) {
    rules.a[i].support = kQuadricRest.data();
    rules.a[i].size = 7;
    for (int j = 0; j < 7; ++j) rules.a[i].coefficient[j] = solved(i, j);
  }
  // Step 2.
  Poly s[2];
  for (int k = 0; k < 2; ++k) {
    s[k].fill(0);
    AddShifted(rules.a[k + 1], 1, 0, 0, 1.0, &s[k]);   // x·A₂, x·A₃
    AddShifted(rules.a[k], 0, 1, 0, -1.0, &s[k]);      // −y·A₁, −y·A₂
    Reduce(rules, &s[k]);
  }
  const int xz2 = Index(1, 0, 2), yz2 = Index(0, 1, 2);
  const Eigen::Matrix2d m2 = (Eigen::Matrix2d() << s[0][xz2], s[0][yz2], s[1][xz2], s[1][yz2])
                                 .finished();
  if (!(std::abs(m2.determinant()) > 1e-6 * MaxAbs(s[0]) * MaxAbs(s[1]))) return false;
  const Eigen::Matrix2d m2_inverse = m2.inverse();
  int basis[kBasis];
  for (int j = 0; j < kBasis; ++j) {
    const Exponent e = kBasisMonomials[j];
    basis[j] = Index(e.x, e.y, e.z);
  }
  for (int k = 0; k < 2; ++k) {
    rules.e[k].support = kBasisMonomials.data();
    rules.e[k].size = kBasis;
    for (int j = 0; j < kBasis; ++j) {
      rules.e[k].coefficient[j] =
          -(m2_inverse(k, 0) * s[0][basis[j]] + m2_inverse(k, 1) * s[1][basis[j]]);
    }
  }
  rules.with_e = true;
  // Step 3: the S-pairs of x² ≡ A₁ with xz² ≡ E₁ and of y² ≡ A₃ with
  // yz² ≡ E₂ (lcm x²z², y²z²): z²A₁ − xE₁ and z²A₃ − yE₂, reduced, relate z⁴
  // to β. The one whose z⁴ coefficient survives the reduction best (relative
  // to the pair's own coefficients) is used.
  const int z4 = Index(0, 0, 4);
  Poly best{};
  double best_ratio = 0;
  for (int k = 0; k < 2; ++k) {
    Poly r{};
    AddShifted(rules.a[2 * k], 0, 0, 2, 1.0, &r);             // z²A₁, z²A₃
    AddShifted(rules.e[k], k == 0 ? 1 : 0, k, 0, -1.0, &r);   // −xE₁, −yE₂
    const double input_scale = MaxAbs(r);
    Reduce(rules, &r);
    const double ratio = std::abs(r[z4]) / input_scale;
    if (ratio > best_ratio) {
      best_ratio = ratio;
      best = r;
    }
  }
  if (!(best_ratio > 1e-6)) return false;
  // Rows: z·z³ = z⁴, z·xz = xz², z·yz = yz².
  for (int j = 0; j < kBasis; ++j) {
    rows[0][j] = -best[basis[j]] / best[z4];
    rows[1][j] = rules.e[0].coefficient[j];
    rows[2][j] = rules.e[1].coefficient[j];
  }
  return true;
}

}  // namespace normal_form

// Newton steps on the three quadrics (until the step is negligible, at most
// 4): the eigenvectors of the action matrix carry its conditioning; Newton
// restores full precision.
void PolishRoot(const Eigen::Matrix<double, 3, 10>& quadrics, Eigen::Vector3d* xyz) {
  for (int iteration = 0; iteration < 4; ++iteration) {
    const double x = xyz->x(), y = xyz->y(), z = xyz->z();
    Eigen::Matrix<double, 10, 1> mono;
    mono << 1, x, y, z, x * x, x * y, x * z, y * y, y * z, z * z;
    Eigen::Matrix<double, 10, 3> d = Eigen::Matrix<double, 10, 3>::Zero();
    d(1, 0) = 1;
    d(2, 1) = 1;
    d(3, 2) = 1;
    d.row(4) << 2 * x, 0, 0;
    d.row(5) << y, x, 0;
    d.row(6) << z, 0, x;
    d.row(7) << 0, 2 * y, 0;
    d.row(8) << 0, z, y;
    d.row(9) << 0, 0, 2 * z;
    const Eigen::Vector3d f = quadrics * mono;
    const Eigen::Matrix3d jacobian = quadrics * d;
    // Cramer's rule: J⁻¹ f = adj(J) f / det J, with adj(J)'s rows the cross
    // products of J's columns.
    const Eigen::Vector3d j0 = jacobian.col(0), j1 = jacobian.col(1), j2 = jacobian.col(2);
    const Eigen::Vector3d r0 = j1.cross(j2);
    const double det = j0.dot(r0);
    const Eigen::Vector3d step =
        Eigen::Vector3d(r0.dot(f), j2.cross(j0).dot(f), j0.cross(j1).dot(f)) / det;
    if (!step.allFinite()) return;
    *xyz -= step;
    if (step.norm() < 1e-14 * std::max(1.0, xyz->norm())) return;
  }
}

// The same action rows from the 26 × 34 elimination template (Gaussian
// elimination with partial pivoting): the fallback for the rare quadrics whose
// hand-derived reduction meets a poorly conditioned pivot.
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

}  // namespace

int IntersectThreeQuadrics(const Eigen::Matrix<double, 3, 10>& quadrics,
                           std::vector<Eigen::Vector3d>* out) {
  out->clear();
  if (!quadrics.allFinite()) return 0;
  if (!(quadrics.cwiseAbs().maxCoeff() > 0)) return 0;
  // The rows of the action of z (multiplication by z on the basis
  // β = (z³, xz, yz, z², x, y, z, 1)) that are not unit rows: the normal forms
  // of z⁴, xz², yz². Its unit rows restate z·z² = z³, z·x = xz, z·y = yz,
  // z·z = z², z·1 = z.
  double action[3][8];
  if (!normal_form::ActionRows(quadrics, action) && !TemplateActionRows(quadrics, action)) {
    return 0;
  }
  for (const auto& row : action) {
    for (double v : row) {
      if (!std::isfinite(v)) return 0;
    }
  }
  // Eigenvalues of the action without an eigen-decomposition. At a root the
  // basis monomials β = (z³, xz, yz, z², x, y, z, 1) satisfy action·β = z·β;
  // its five unit rows only restate β, and the three others are linear in
  // (x, y) for a fixed z:
  //     X_b(z) x + Y_b(z) y + C_b(z) = 0,   b = 0, 1, 2,
  // so z is a root of det[X Y C] (degree 8, leading coefficient ±1: the
  // characteristic polynomial of the action), whose real roots come from
  // Sturm sequences; (x, y) then from the 3 × 2 linear system.
  std::array<std::array<double, 3>, 3> px{}, py{};
  std::array<std::array<double, 5>, 3> pc{};
  for (int b = 0; b < 3; ++b) {
    px[b] = {action[b][4], action[b][1], b == 1 ? -1.0 : 0.0};
    py[b] = {action[b][5], action[b][2], b == 2 ? -1.0 : 0.0};
    pc[b] = {action[b][7], action[b][6], action[b][3], action[b][0], b == 0 ? -1.0 : 0.0};
  }
  // Y_i C_j − Y_j C_i (degree 6), then the expansion along the X column.
  const auto minor = [&](int i, int j) {
    std::array<double, 7> m{};
    for (int a = 0; a < 3; ++a) {
      for (int c = 0; c < 5; ++c) m[a + c] += py[i][a] * pc[j][c] - py[j][a] * pc[i][c];
    }
    return m;
  };
  const std::array<std::array<double, 7>, 3> minors = {minor(1, 2), minor(0, 2), minor(0, 1)};
  std::array<double, 9> det{};
  for (int b = 0; b < 3; ++b) {
    const double sign = b == 1 ? -1.0 : 1.0;
    for (int a = 0; a < 3; ++a) {
      for (int c = 0; c < 7; ++c) det[a + c] += sign * px[b][a] * minors[b][c];
    }
  }
  double z_roots[8];
  const int num_roots = poly::SturmRealRoots(det.data(), 8, z_roots);
  for (int k = 0; k < num_roots; ++k) {
    const double z = z_roots[k];
    Eigen::Matrix<double, 3, 2> m;
    Eigen::Vector3d rhs;
    for (int b = 0; b < 3; ++b) {
      m(b, 0) = (px[b][2] * z + px[b][1]) * z + px[b][0];
      m(b, 1) = (py[b][2] * z + py[b][1]) * z + py[b][0];
      rhs[b] = -((((pc[b][4] * z + pc[b][3]) * z + pc[b][2]) * z + pc[b][1]) * z + pc[b][0]);
    }
    // (x, y) from the consistent 3 × 2 system m (x, y)ᵀ = rhs: with n the
    // cross product of m's columns, x = (rhs × m₁)·n / |n|², y = (m₀ × rhs)·n
    // / |n|² (exact when rhs lies in their span, the least-squares solution
    // otherwise). Rank < 2: (x, y) not determined by this root (a solution at
    // infinity or a degenerate configuration).
    const Eigen::Vector3d c0 = m.col(0), c1 = m.col(1);
    const Eigen::Vector3d n = c0.cross(c1);
    const double n2 = n.squaredNorm();
    if (!(n2 > 1e-24 * c0.squaredNorm() * c1.squaredNorm())) continue;
    const Eigen::Vector2d xy(rhs.cross(c1).dot(n) / n2, c0.cross(rhs).dot(n) / n2);
    Eigen::Vector3d xyz(xy.x(), xy.y(), z);
    PolishRoot(quadrics, &xyz);
    if (xyz.allFinite()) out->push_back(xyz);
  }
  return static_cast<int>(out->size());
}

int m_p4l_l(std::span<const PluckerLine> lines,
            std::span<const Eigen::Vector3d> points_local, std::vector<Sim3d>* out) {
  out->clear();
  // Normalise both sides: centroid at the origin, unit RMS radius.
  Eigen::Vector3d mean_local = Eigen::Vector3d::Zero(), mean_world = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, 4> anchors;
  for (int i = 0; i < 4; ++i) {
    if (!points_local[i].allFinite() || !lines[i].v.allFinite() ||
        !lines[i].w.allFinite() || !(lines[i].v.squaredNorm() > 0)) {
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

  // Rows: u ⟂ v_i; A m + U t' = b with m the quaternion monomials.
  constexpr int kEq = 8;
  Eigen::Matrix<double, kEq, 10> a;
  Eigen::Matrix<double, kEq, 3> u;
  Eigen::Matrix<double, kEq, 1> b;
  for (int i = 0; i < 4; ++i) {
    const Eigen::Vector3d p =
        PreRotation().transpose() * ((points_local[i] - mean_local) / spread_local);
    const Eigen::Matrix<double, 3, 10> coeffs = RotateCoefficients(p);
    const Eigen::Vector3d anchor = (anchors[i] - mean_world) / spread_world;
    Eigen::Vector3d basis[2];
    upright::OrthogonalBasis(lines[i].v.normalized(), &basis[0], &basis[1]);
    for (int k = 0; k < 2; ++k) {
      a.row(2 * i + k) = basis[k].transpose() * coeffs;
      u.row(2 * i + k) = basis[k].transpose();
      b[2 * i + k] = basis[k].dot(anchor);
    }
  }
  // Eliminate t' from the first seven equations: the last four rows of Qᵀ.
  constexpr int kUsed = 7;
  const Eigen::HouseholderQR<Eigen::Matrix<double, kUsed, 3>> qr(u.topRows<kUsed>());
  const Eigen::Matrix<double, kUsed, 3> r_full = qr.matrixQR();
  const double r_diag_min = std::min({std::abs(r_full(0, 0)), std::abs(r_full(1, 1)),
                                      std::abs(r_full(2, 2))});
  if (!(r_diag_min > 1e-10)) return 0;  // lines (nearly) parallel
  const Eigen::Matrix<double, kUsed, kUsed> qt =
      qr.householderQ().transpose() * Eigen::Matrix<double, kUsed, kUsed>::Identity();
  const Eigen::Matrix<double, 4, 10> g = qt.bottomRows<4>() * a.topRows<kUsed>();
  const Eigen::Vector4d h = qt.bottomRows<4>() * b.head<kUsed>();
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

  struct Candidate {
    double residual;
    Sim3d local_from_world;
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
    // t' by least squares over the seven equations: R t' = (Qᵀ (b − A m))₀..₂.
    const Eigen::Matrix<double, kUsed, 1> rhs =
        qt * (b.head<kUsed>() - a.topRows<kUsed>() * mono);
    const Eigen::Vector3d t_norm =
        r_full.topLeftCorner<3, 3>().triangularView<Eigen::Upper>().solve(rhs.head<3>());
    const double residual =
        std::abs(a.row(kEq - 1).dot(mono) + u.row(kEq - 1).dot(t_norm) - b[kEq - 1]);
    // Undo the normalisation: world = σ_w (M' Pᵀ (X̃ − μ_l) / σ_l + t') + μ_w.
    const double s_norm = q.squaredNorm();
    const Eigen::Quaterniond rotation_norm(q[0], q[1], q[2], q[3]);
    const Eigen::Matrix3d rotation =
        rotation_norm.normalized().toRotationMatrix() * PreRotation().transpose();
    const double scale = s_norm * spread_world / spread_local;
    const Eigen::Vector3d translation =
        spread_world * t_norm + mean_world - scale * (rotation * mean_local);
    const Sim3d world_from_local(scale, Eigen::Quaterniond(rotation), translation);
    if (!std::isfinite(scale) || !translation.allFinite() || count == 8) continue;
    candidates[count++] = {residual, world_from_local.Inverse()};
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
    if (candidates[i].residual > std::max(1e-9, 100 * candidates[0].residual)) break;
    out->push_back(candidates[i].local_from_world);
  }
  return static_cast<int>(out->size());
}

}  // namespace linecloud
