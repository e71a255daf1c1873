#include "linecloud/solvers/p6l.h"

#include "linecloud/util/check.h"
#include "linecloud/util/multiversion.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "linecloud/solvers/eigenvalues.h"
#include "linecloud/solvers/p6l_template.h"

namespace linecloud {
namespace {

namespace tpl = p6l_template;
using tpl::Exponent;

// Monomials in s = (x, y, z) of degree ≤ 8, graded: those of degree ≤ d are
// the first (d+1)(d+2)(d+3)/6 (1, 10, 35, 84, 165 for d = 0, 2, 4, 6, 8).
constexpr int kMaxDegree = 8;
constexpr int kQuadratic = 10;
constexpr int kQuartic = 35;
constexpr int kSextic = 84;
constexpr int kOctic = 165;

struct Monomials {
  std::array<Exponent, kOctic> exponent;
  std::array<std::array<std::array<int, kMaxDegree + 1>, kMaxDegree + 1>, kMaxDegree + 1> index;
  // product[i][j]: index of monomial i × monomial j (i, j < 84, degree ≤ 8),
  // −1 past degree 8.
  std::array<std::array<int16_t, kSextic>, kSextic> product;

  int Index(int x, int y, int z) const { return index[x][y][z]; }
};

Monomials MakeMonomials() {
  Monomials m{};
  for (auto& plane : m.index) {
    for (auto& row : plane) row.fill(-1);
  }
  int next = 0;
  for (int d = 0; d <= kMaxDegree; ++d) {
    for (int x = d; x >= 0; --x) {
      for (int y = d - x; y >= 0; --y) {
        const int z = d - x - y;
        m.exponent[next] = {x, y, z};
        m.index[x][y][z] = next++;
      }
    }
  }
  for (int i = 0; i < kSextic; ++i) {
    for (int j = 0; j < kSextic; ++j) {
      const Exponent a = m.exponent[i], b = m.exponent[j];
      const int x = a.x + b.x, y = a.y + b.y, z = a.z + b.z;
      m.product[i][j] = static_cast<int16_t>(x + y + z <= kMaxDegree ? m.index[x][y][z] : -1);
    }
  }
  return m;
}

const Monomials& Mono() {
  static const Monomials m = MakeMonomials();
  return m;
}

// Template columns: eliminated | reducible | basis. column[r][k] is the column
// of sextic monomial k times row r's multiplier. action[b] says where x·B_b
// lands: ≥ 0 a basis index, < 0 the reducible monomial −1 − action[b].
struct Layout {
  std::array<std::array<int16_t, kSextic>, tpl::kRows> column;
  std::array<int, tpl::kBasis> action;
  // ratio[k]: pairs (i, j) of basis indices with B_j = s_k · B_i. s_k is read
  // off an eigenvector as v_j / v_i with the largest |v_i|: low-degree pairs
  // for small |s|, high-degree pairs for large |s| (rotations near 180°).
  std::array<std::vector<std::pair<int, int>>, 3> ratio;
  // Chains of the action: B_b = x^power[b] · B_start, with start of x-degree 0.
  // Along a chain the eigenvector of eigenvalue λ is v_b = λ^power[b] u_chain;
  // chain_end[c] is the basis index whose x-multiple is reducible.
  std::array<int, tpl::kBasis> chain, power;
  std::array<int, tpl::kReducible> chain_end;
};

Layout MakeLayout() {
  Layout layout{};
  const Monomials& mono = Mono();
  const auto key = [](const Exponent& e) { return (e.x * 16 + e.y) * 16 + e.z; };
  std::array<int, 16 * 16 * 16> column;
  column.fill(-1);
  std::array<int, 16 * 16 * 16> basis_index;
  basis_index.fill(-1);
  for (int i = 0; i < tpl::kBasis; ++i) {
    column[key(tpl::kBasisMonomials[i])] = tpl::kEliminated + tpl::kReducible + i;
    basis_index[key(tpl::kBasisMonomials[i])] = i;
  }
  for (int i = 0; i < tpl::kReducible; ++i) {
    column[key(tpl::kReducibleMonomials[i])] = tpl::kEliminated + i;
  }
  int next = 0;
  for (int r = 0; r < tpl::kRows; ++r) {
    const Exponent m = tpl::kTemplateRows[r].multiplier;
    for (int k = 0; k < kSextic; ++k) {
      const Exponent e = mono.exponent[k];
      const int c = key({e.x + m.x, e.y + m.y, e.z + m.z});
      if (column[c] < 0) column[c] = next++;
      layout.column[r][k] = static_cast<int16_t>(column[c]);
    }
  }
  for (int b = 0; b < tpl::kBasis; ++b) {
    const Exponent e = tpl::kBasisMonomials[b];
    const int target = key({e.x + 1, e.y, e.z});
    layout.action[b] =
        basis_index[target] >= 0 ? basis_index[target] : -1 - (column[target] - tpl::kEliminated);
  }
  int chains = 0;
  std::array<int, 16 * 16 * 16> chain_of_start;
  chain_of_start.fill(-1);
  for (int b = 0; b < tpl::kBasis; ++b) {
    const Exponent e = tpl::kBasisMonomials[b];
    const int start = key({0, e.y, e.z});
    if (chain_of_start[start] < 0) chain_of_start[start] = chains++;
    layout.chain[b] = chain_of_start[start];
    layout.power[b] = e.x;
  }
  for (int b = 0; b < tpl::kBasis; ++b) {
    if (layout.action[b] < 0) layout.chain_end[layout.chain[b]] = b;
  }
  for (int b = 0; b < tpl::kBasis; ++b) {
    const Exponent e = tpl::kBasisMonomials[b];
    const Exponent shifted[3] = {{e.x + 1, e.y, e.z}, {e.x, e.y + 1, e.z}, {e.x, e.y, e.z + 1}};
    for (int k = 0; k < 3; ++k) {
      const int j = basis_index[key(shifted[k])];
      if (j >= 0) layout.ratio[k].emplace_back(b, j);
    }
  }
  return layout;  // next == kEliminated for the generated template
}

const Layout& TemplateLayout() {
  static const Layout layout = MakeLayout();
  return layout;
}

using Quadric = std::array<double, kQuadratic>;
using Quartic = std::array<double, kQuartic>;
using Sextic = std::array<double, kSextic>;
using Octic = std::array<double, kOctic>;

// out += scale · a · b for polynomials with na and nb monomials.
template <size_t NA, size_t NB, size_t NOut>
void MulAdd(const std::array<double, NA>& a, const std::array<double, NB>& b, double scale,
            std::array<double, NOut>* out) {
  const Monomials& mono = Mono();
  for (size_t i = 0; i < NA; ++i) {
    const double ai = scale * a[i];
    if (ai == 0) continue;
    for (size_t j = 0; j < NB; ++j) (*out)[mono.product[i][j]] += ai * b[j];
  }
}

// Coefficients of R̃u = (1 − |s|²) u + 2 s × u + 2 s (s·u): three quadrics,
// stored as a 3-vector per monomial.
std::array<Eigen::Vector3d, kQuadratic> CayleyTimes(const Eigen::Vector3d& u) {
  const Monomials& mono = Mono();
  std::array<Eigen::Vector3d, kQuadratic> c;
  c[mono.Index(0, 0, 0)] = u;
  for (int k = 0; k < 3; ++k) {
    const int e[3] = {k == 0, k == 1, k == 2};
    c[mono.Index(e[0], e[1], e[2])] = 2 * Eigen::Vector3d::Unit(k).cross(u);
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = i; j < 3; ++j) {
      int e[3] = {0, 0, 0};
      ++e[i];
      ++e[j];
      Eigen::Vector3d coefficient;
      if (i == j) {
        coefficient = -u + 2 * u[i] * Eigen::Vector3d::Unit(i);
      } else {
        coefficient = 2 * (u[j] * Eigen::Vector3d::Unit(i) + u[i] * Eigen::Vector3d::Unit(j));
      }
      c[mono.Index(e[0], e[1], e[2])] = coefficient;
    }
  }
  return c;
}

// Quotient of an octic by 1 + x² + y² + z² (exact division; the remainder,
// zero in exact arithmetic, is dropped). Long division in x from the top.
Sextic DivideByNorm(Octic a) {
  const Monomials& mono = Mono();
  Sextic q{};
  for (int k = kMaxDegree; k >= 2; --k) {
    for (int y = kMaxDegree - k; y >= 0; --y) {
      for (int z = kMaxDegree - k - y; z >= 0; --z) {
        const double value = a[mono.Index(k, y, z)];
        if (value == 0) continue;
        q[mono.Index(k - 2, y, z)] = value;
        a[mono.Index(k - 2, y, z)] -= value;
        a[mono.Index(k - 2, y + 2, z)] -= value;
        a[mono.Index(k - 2, y, z + 2)] -= value;
      }
    }
  }
  return q;
}

// The 15 sextics of a normalised sample (rays (d, m), lines (v, w)).
void BuildSextics(const std::array<Eigen::Vector3d, 6>& d, const std::array<Eigen::Vector3d, 6>& m,
                  const std::array<Eigen::Vector3d, 6>& v, const std::array<Eigen::Vector3d, 6>& w,
                  std::array<Sextic, 15>* sextics) {
  // Rows of the 6 × 4 matrix: a_i = R̃v_i × d_i (3 quadrics), b_i.
  std::array<std::array<Quadric, 3>, 6> a;
  std::array<Quadric, 6> b;
  for (int i = 0; i < 6; ++i) {
    const auto rv = CayleyTimes(v[i]);
    const auto rw = CayleyTimes(w[i]);
    for (int k = 0; k < kQuadratic; ++k) {
      const Eigen::Vector3d cross = rv[k].cross(d[i]);
      for (int c = 0; c < 3; ++c) a[i][c][k] = cross[c];
      b[i][k] = d[i].dot(rw[k]) + m[i].dot(rv[k]);
    }
  }
  // a_j × a_k for j < k (quartics), then the 3 × 3 minors a_i · (a_j × a_k).
  std::array<std::array<std::array<Quartic, 3>, 6>, 6> cross{};
  for (int j = 0; j < 6; ++j) {
    for (int k = j + 1; k < 6; ++k) {
      for (int c = 0; c < 3; ++c) {
        const int c1 = (c + 1) % 3, c2 = (c + 2) % 3;
        Quartic& out = cross[j][k][c];
        out.fill(0);
        MulAdd(a[j][c1], a[k][c2], 1.0, &out);
        MulAdd(a[j][c2], a[k][c1], -1.0, &out);
      }
    }
  }
  std::array<Sextic, 20> minor3;
  std::array<std::array<std::array<int, 6>, 6>, 6> triple{};
  int count = 0;
  for (int i = 0; i < 6; ++i) {
    for (int j = i + 1; j < 6; ++j) {
      for (int k = j + 1; k < 6; ++k) {
        Sextic& out = minor3[count];
        out.fill(0);
        for (int c = 0; c < 3; ++c) MulAdd(a[i][c], cross[j][k][c], 1.0, &out);
        triple[i][j][k] = count++;
      }
    }
  }
  // 4 × 4 minors by expansion along the last column, divided by 1 + |s|².
  int e = 0;
  for (int i0 = 0; i0 < 6; ++i0) {
    for (int i1 = i0 + 1; i1 < 6; ++i1) {
      for (int i2 = i1 + 1; i2 < 6; ++i2) {
        for (int i3 = i2 + 1; i3 < 6; ++i3) {
          Octic octic{};
          MulAdd(b[i0], minor3[triple[i1][i2][i3]], -1.0, &octic);
          MulAdd(b[i1], minor3[triple[i0][i2][i3]], 1.0, &octic);
          MulAdd(b[i2], minor3[triple[i0][i1][i3]], -1.0, &octic);
          MulAdd(b[i3], minor3[triple[i0][i1][i2]], 1.0, &octic);
          (*sextics)[e++] = DivideByNorm(octic);
        }
      }
    }
  }
}

// The template T = [T_sq | T_B] (kRows × kCols, column-major) reduced to the
// rows the action matrix needs: R = the reducible rows of T_sq⁻¹ T_B. Gaussian
// elimination with partial pivoting on the square block, applied to all
// columns at once (P T = L [U | L⁻¹ P T_B]); then back substitution with the
// trailing kReducible × kReducible block of U only. Writes R (kReducible ×
// kBasis, column-major); false on a zero pivot or a non-finite result.
// Plain loops on raw storage, cloned for AVX2/FMA (util/multiversion.h).
LINECLOUD_TARGET_CLONES bool EliminateTemplate(double* t, double* reduced) {
  constexpr int kSquare = tpl::kEliminated + tpl::kReducible;
  constexpr int ld = tpl::kRows;
  for (int k = 0; k < kSquare; ++k) {
    double* column_k = t + k * ld;
    int pivot = k;
    double largest = std::abs(column_k[k]);
    for (int i = k + 1; i < tpl::kRows; ++i) {
      if (std::abs(column_k[i]) > largest) {
        largest = std::abs(column_k[i]);
        pivot = i;
      }
    }
    if (!(largest > 0) || !std::isfinite(largest)) return false;
    if (pivot != k) {
      for (int j = k; j < tpl::kCols; ++j) std::swap(t[j * ld + k], t[j * ld + pivot]);
    }
    const double inverse = 1.0 / column_k[k];
    for (int i = k + 1; i < tpl::kRows; ++i) column_k[i] *= inverse;
    for (int j = k + 1; j < tpl::kCols; ++j) {
      double* column = t + j * ld;
      const double a = column[k];
      if (a == 0) continue;  // the template is sparse: skip untouched columns
      for (int i = k + 1; i < tpl::kRows; ++i) column[i] -= a * column_k[i];
    }
  }
  // U_rr R = F_r, column by column of the right-hand side (column-oriented
  // back substitution: the columns of U are contiguous).
  constexpr int r0 = tpl::kEliminated;
  for (int b = 0; b < tpl::kBasis; ++b) {
    double x[tpl::kReducible];
    const double* f = t + (kSquare + b) * ld + r0;
    for (int i = 0; i < tpl::kReducible; ++i) x[i] = f[i];
    for (int i = tpl::kReducible - 1; i >= 0; --i) {
      const double* u = t + (r0 + i) * ld + r0;
      x[i] /= u[i];
      for (int r = 0; r < i; ++r) x[r] -= x[i] * u[r];
    }
    double* out = reduced + b * tpl::kReducible;
    for (int i = 0; i < tpl::kReducible; ++i) {
      if (!std::isfinite(x[i])) return false;
      out[i] = x[i];
    }
  }
  return true;
}

// Real roots s of the 15 sextics (imaginary part small), unpolished.
void SolveSextics(const std::array<Sextic, 15>& sextics, std::vector<Eigen::Vector3d>* roots) {
  roots->clear();
  const Layout& layout = TemplateLayout();
  thread_local Eigen::MatrixXd t;
  t.setZero(tpl::kRows, tpl::kCols);
  std::array<double, 15> scale;
  for (int e = 0; e < 15; ++e) {
    double largest = 0;
    for (double c : sextics[e]) largest = std::max(largest, std::abs(c));
    scale[e] = largest > 0 ? 1.0 / largest : 0.0;
  }
  for (int r = 0; r < tpl::kRows; ++r) {
    const int eq = tpl::kTemplateRows[r].equation;
    for (int k = 0; k < kSextic; ++k) t(r, layout.column[r][k]) = scale[eq] * sextics[eq][k];
  }
  thread_local Eigen::MatrixXd reduced;
  reduced.resize(tpl::kReducible, tpl::kBasis);
  if (!EliminateTemplate(t.data(), reduced.data())) return;
  thread_local Eigen::MatrixXd action;
  action.setZero(tpl::kBasis, tpl::kBasis);
  for (int b = 0; b < tpl::kBasis; ++b) {
    const int target = layout.action[b];
    if (target >= 0) {
      action(b, target) = 1.0;
    } else {
      action.row(b) = -reduced.row(-1 - target);
    }
  }
  // Eigenvalues only (eigenvalues.h: no Schur vectors); the eigenvector of each real one
  // comes from the chain structure: v_b = λ^power[b] u_chain[b], where u is the
  // null vector of the 26 × 26 matrix P(λ) of the nontrivial rows
  //     Σ_j A(end_c, j) λ^power[j] u_chain[j] − λ^(power[end_c] + 1) u_c = 0.
  thread_local Eigen::MatrixXd scratch;
  thread_local std::vector<std::complex<double>> values;
  scratch = action;
  if (!EigenvaluesInPlace(&scratch, &values)) {
    // Rare non-convergence of the cheap iteration: Eigen's real Schur form.
    const Eigen::EigenSolver<Eigen::MatrixXd> eig(action, false);
    if (eig.info() != Eigen::Success) return;
    values.assign(eig.eigenvalues().begin(), eig.eigenvalues().end());
  }
  for (const std::complex<double>& value : values) {
    if (std::abs(value.imag()) > 1e-4 * std::max(1.0, std::abs(value))) continue;
    // Inverse iteration: P(λ) u = 1 from a fixed generic right-hand side. An
    // exactly singular pivot (λ exact to the last bit) is retried with λ
    // nudged by a few ulps, as usual for inverse iteration.
    double lambda = value.real();
    std::array<double, kMaxDegree + 2> powers;
    Eigen::Matrix<double, tpl::kReducible, 1> u;
    for (int attempt = 0; attempt < 2; ++attempt) {
      if (attempt == 1) lambda += 1e-13 * std::max(1.0, std::abs(lambda));
      powers[0] = 1;
      for (int k = 1; k < kMaxDegree + 2; ++k) powers[k] = powers[k - 1] * lambda;
      Eigen::Matrix<double, tpl::kReducible, tpl::kReducible> p =
          Eigen::Matrix<double, tpl::kReducible, tpl::kReducible>::Zero();
      for (int c = 0; c < tpl::kReducible; ++c) {
        const int end = layout.chain_end[c];
        for (int j = 0; j < tpl::kBasis; ++j) {
          p(c, layout.chain[j]) += action(end, j) * powers[layout.power[j]];
        }
        p(c, c) -= powers[layout.power[end] + 1];
      }
      u = p.partialPivLu().solve(Eigen::Matrix<double, tpl::kReducible, 1>::Constant(1.0));
      if (u.allFinite()) break;
    }
    if (!u.allFinite()) continue;
    Eigen::Matrix<double, tpl::kBasis, 1> vec;
    for (int b = 0; b < tpl::kBasis; ++b) vec[b] = powers[layout.power[b]] * u[layout.chain[b]];
    Eigen::Vector3d s;
    for (int k = 0; k < 3; ++k) {
      double largest = 0;
      double value = 0;
      for (const auto& [from, to] : layout.ratio[k]) {
        const double magnitude = std::abs(vec[from]);
        if (magnitude > largest) {
          largest = magnitude;
          value = vec[to] / vec[from];
        }
      }
      s[k] = largest > 0 ? value : std::numeric_limits<double>::quiet_NaN();
    }
    if (s.allFinite()) roots->push_back(s);
  }
}

Eigen::Matrix3d CayleyRotation(const Eigen::Vector3d& s) {
  const Eigen::Matrix3d skew =
      (Eigen::Matrix3d() << 0, -s.z(), s.y(), s.z(), 0, -s.x(), -s.y(), s.x(), 0).finished();
  return ((1 - s.squaredNorm()) * Eigen::Matrix3d::Identity() + 2 * skew + 2 * s * s.transpose()) /
         (1 + s.squaredNorm());
}

struct Normalised {
  std::array<Eigen::Vector3d, 6> d, m, v, w, origin;
};

// r_i = d_iᵀ (R w_i + t × R v_i) + m_iᵀ R v_i.
Eigen::Matrix<double, 6, 1> Residuals(const Normalised& n, const Eigen::Matrix3d& r,
                                      const Eigen::Vector3d& t) {
  Eigen::Matrix<double, 6, 1> out;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d rv = r * n.v[i];
    out[i] = n.d[i].dot(r * n.w[i] + t.cross(rv)) + n.m[i].dot(rv);
  }
  return out;
}

// t from R by least squares: (R v_i × d_i)ᵀ t = −(d_iᵀ R w_i + m_iᵀ R v_i).
Eigen::Vector3d TranslationFor(const Normalised& n, const Eigen::Matrix3d& r) {
  Eigen::Matrix<double, 6, 3> a;
  Eigen::Matrix<double, 6, 1> b;
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d rv = r * n.v[i];
    a.row(i) = rv.cross(n.d[i]).transpose();
    b[i] = -(n.d[i].dot(r * n.w[i]) + n.m[i].dot(rv));
  }
  return (a.transpose() * a).ldlt().solve(a.transpose() * b);
}

// Newton steps on the six equations in (R, t), R ← exp([δθ]×) R, t ← t + δt.
void Polish(const Normalised& n, Eigen::Matrix3d* r, Eigen::Vector3d* t) {
  for (int iteration = 0; iteration < 6; ++iteration) {
    Eigen::Matrix<double, 6, 6> jacobian;
    Eigen::Matrix<double, 6, 1> residual;
    for (int i = 0; i < 6; ++i) {
      const Eigen::Vector3d rv = *r * n.v[i], rw = *r * n.w[i];
      residual[i] = n.d[i].dot(rw + t->cross(rv)) + n.m[i].dot(rv);
      jacobian.block<1, 3>(i, 0) =
          (rw.cross(n.d[i]) + rv.cross(n.d[i].cross(*t)) + rv.cross(n.m[i])).transpose();
      jacobian.block<1, 3>(i, 3) = rv.cross(n.d[i]).transpose();
    }
    const Eigen::Matrix<double, 6, 1> step = jacobian.partialPivLu().solve(-residual);
    if (!step.allFinite()) return;
    const Eigen::Vector3d angle = step.head<3>();
    if (angle.norm() > 0) {
      *r = Eigen::AngleAxisd(angle.norm(), angle.normalized()).toRotationMatrix() * *r;
    }
    *t += step.tail<3>();
    if (step.norm() < 1e-15 * (1 + t->norm())) return;
  }
}

// Depth along each ray of its closest point to the moved line; false when a
// ray meets its line behind its camera (rays parallel to their line skipped).
bool InFront(const Normalised& n, const Eigen::Matrix3d& r, const Eigen::Vector3d& t) {
  for (int i = 0; i < 6; ++i) {
    const Eigen::Vector3d v = r * n.v[i];
    const Eigen::Vector3d w = r * n.w[i] + t.cross(v);
    const Eigen::Vector3d anchor = v.cross(w) / v.squaredNorm();
    const Eigen::Vector3d normal = n.d[i].cross(v);
    const double sin2 = normal.squaredNorm();
    if (sin2 < 1e-12) continue;
    const double depth = (anchor - n.origin[i]).cross(v).dot(normal) / sin2;
    if (depth < 0) return false;
  }
  return true;
}

// A fixed generic rotation of the world before solving, so that structured
// poses (identity, 180° turns about an axis) do not sit on the Cayley
// singularity |s| = ∞.
const Eigen::Matrix3d& PreRotation() {
  static const Eigen::Matrix3d r =
      Eigen::Quaterniond(0.3961, -0.2709, 0.6842, 0.5476).normalized().toRotationMatrix();
  return r;
}

}  // namespace

int m_p6l(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
          std::span<const PluckerLine> lines, std::vector<Rigid3d>* out) {
  CheckMinimalSample("m_p6l", 6, out, origins, directions, lines);
  out->clear();
  // Normalise: rig origin at the rays' centroid, world origin at the lines'
  // anchor centroid, both scaled by the spread of the anchors.
  Eigen::Vector3d rig_centre = Eigen::Vector3d::Zero(), world_centre = Eigen::Vector3d::Zero();
  std::array<Eigen::Vector3d, 6> anchors;
  for (int i = 0; i < 6; ++i) {
    if (!origins[i].allFinite() || !directions[i].allFinite() || !lines[i].v.allFinite() ||
        !lines[i].w.allFinite() || !(directions[i].norm() > 0) || !(lines[i].v.norm() > 0)) {
      return 0;
    }
    anchors[i] = lines[i].Anchor() / lines[i].v.squaredNorm();
    rig_centre += origins[i] / 6;
    world_centre += anchors[i] / 6;
  }
  double spread = 0;
  for (int i = 0; i < 6; ++i) spread += (anchors[i] - world_centre).squaredNorm() / 6;
  spread = std::sqrt(spread);
  if (!(spread > 1e-12 * (1 + world_centre.norm()))) spread = 1;
  Normalised n;
  for (int i = 0; i < 6; ++i) {
    n.d[i] = directions[i].normalized();
    n.origin[i] = (origins[i] - rig_centre) / spread;
    n.m[i] = n.origin[i].cross(n.d[i]);
    n.v[i] = PreRotation() * lines[i].v.normalized();
    const Eigen::Vector3d point = PreRotation() * (anchors[i] - world_centre) / spread;
    n.w[i] = point.cross(n.v[i]);
  }
  std::array<Sextic, 15> sextics;
  BuildSextics(n.d, n.m, n.v, n.w, &sextics);
  thread_local std::vector<Eigen::Vector3d> roots;
  SolveSextics(sextics, &roots);

  double scale = 0;
  for (int i = 0; i < 6; ++i) scale = std::max({scale, n.w[i].norm(), n.m[i].norm()});
  std::vector<std::pair<Eigen::Matrix3d, Eigen::Vector3d>> kept;
  for (const Eigen::Vector3d& s : roots) {
    Eigen::Matrix3d r = CayleyRotation(s);
    Eigen::Vector3d t = TranslationFor(n, r);
    if (!t.allFinite()) continue;
    Polish(n, &r, &t);
    if (!r.allFinite() || !t.allFinite()) continue;
    const double residual = Residuals(n, r, t).cwiseAbs().maxCoeff();
    if (!(residual < 1e-8 * (1 + scale + t.norm()))) continue;
    if (!InFront(n, r, t)) continue;
    bool duplicate = false;
    for (const auto& [r_kept, t_kept] : kept) {
      if ((r - r_kept).norm() < 1e-9 && (t - t_kept).norm() < 1e-9 * (1 + t.norm())) {
        duplicate = true;
      }
    }
    if (duplicate) continue;
    kept.emplace_back(r, t);
    // Undo the normalisation: x_rig = R' P (X − c_w) + σ t' + c_q.
    const Eigen::Matrix3d rotation = r * PreRotation();
    const Eigen::Vector3d translation = spread * t + rig_centre - rotation * world_centre;
    Eigen::Quaterniond q(rotation);
    q.normalize();
    out->emplace_back(q, translation);
  }
  return static_cast<int>(out->size());
}

int p6l(std::span<const Eigen::Vector3d> bearings, std::span<const PluckerLine> lines,
        std::vector<Rigid3d>* out) {
  CheckMinimalSample("p6l", 6, out, bearings, lines);
  const std::array<Eigen::Vector3d, 6> zero = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                               Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                               Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  return m_p6l(zero, bearings, lines, out);
}

}  // namespace linecloud
