#include "linecloud/solvers/m_p4l_l.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <Eigen/LU>
#include <Eigen/QR>

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
    const Eigen::PartialPivLU<Eigen::Matrix3d> lu(jacobian);
    const Eigen::Vector3d step = lu.solve(f);
    if (!step.allFinite()) return;
    *xyz -= step;
    if (step.norm() < 1e-14 * std::max(1.0, xyz->norm())) return;
  }
}

}  // namespace

int IntersectThreeQuadrics(const Eigen::Matrix<double, 3, 10>& quadrics,
                           std::vector<Eigen::Vector3d>* out) {
  out->clear();
  const TemplateLayout& layout = Layout();
  Eigen::Matrix<double, kRows, kCols> t = Eigen::Matrix<double, kRows, kCols>::Zero();
  for (int r = 0; r < kRows; ++r) {
    for (int k = 0; k < 10; ++k) {
      t(r, layout.column[r][k]) = quadrics(kTemplateRows[r].equation, k);
    }
  }
  const Eigen::PartialPivLU<Eigen::Matrix<double, kRows, kRows>> lu(
      t.leftCols<kRows>());
  // Reducible monomials = −(rows of T_ER⁻¹ T_B) · basis.
  const Eigen::Matrix<double, kRows, kBasis> reduced = lu.solve(t.rightCols<kBasis>());
  if (!reduced.allFinite()) return 0;
  Eigen::Matrix<double, kBasis, kBasis> action = Eigen::Matrix<double, kBasis, kBasis>::Zero();
  action.topRows<kReducible>() = -reduced.bottomRows<kReducible>();
  // z·z² = z³, z·x = xz, z·y = yz, z·z = z², z·1 = z.
  action(3, 0) = 1;
  action(4, 1) = 1;
  action(5, 2) = 1;
  action(6, 3) = 1;
  action(7, 6) = 1;
  if (!action.allFinite()) return 0;
  const Eigen::EigenSolver<Eigen::Matrix<double, kBasis, kBasis>> eig(action, true);
  if (eig.info() != Eigen::Success) return 0;
  const auto& values = eig.eigenvalues();
  const auto& vectors = eig.eigenvectors();
  for (int i = 0; i < kBasis; ++i) {
    if (std::abs(values[i].imag()) > 1e-8 * std::max(1.0, std::abs(values[i]))) continue;
    const auto v = vectors.col(i);
    if (std::abs(v[7]) < 1e-12 * v.norm()) continue;  // solution at infinity
    Eigen::Vector3d xyz((v[4] / v[7]).real(), (v[5] / v[7]).real(), (v[6] / v[7]).real());
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
