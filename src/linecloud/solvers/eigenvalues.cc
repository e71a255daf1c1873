#include "linecloud/solvers/eigenvalues.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include "linecloud/util/multiversion.h"

namespace linecloud {
namespace {

// A ← G⁻¹ A G with G = elementary lower-triangular transforms and row/column
// swaps, column by column; the result is upper Hessenberg.
LINECLOUD_INLINE_INTO_CLONES void ReduceToHessenberg(Eigen::MatrixXd* matrix) {
  Eigen::MatrixXd& a = *matrix;
  const Eigen::Index n = a.rows();
  for (Eigen::Index m = 1; m + 1 < n; ++m) {
    Eigen::Index pivot = m;
    double largest = 0;
    for (Eigen::Index i = m; i < n; ++i) {
      if (std::abs(a(i, m - 1)) > largest) {
        largest = std::abs(a(i, m - 1));
        pivot = i;
      }
    }
    if (largest == 0) continue;
    if (pivot != m) {
      a.row(pivot).swap(a.row(m));
      a.col(pivot).swap(a.col(m));
    }
    const double x = a(m, m - 1);
    // Multipliers of column m − 1 below row m, then G⁻¹ from the left
    // column by column and G from the right (both on contiguous columns).
    const Eigen::Index below = n - m - 1;
    double y[128];
    for (Eigen::Index i = 0; i < below; ++i) {
      y[i] = a(m + 1 + i, m - 1) / x;
      a(m + 1 + i, m - 1) = 0;
    }
    for (Eigen::Index j = m; j < n; ++j) {
      const double pivot_row = a(m, j);
      if (pivot_row == 0) continue;
      double* column = &a(m + 1, j);
      for (Eigen::Index i = 0; i < below; ++i) column[i] -= y[i] * pivot_row;
    }
    double* target = &a(0, m);
    for (Eigen::Index i = 0; i < below; ++i) {
      if (y[i] == 0) continue;
      const double* source = &a(0, m + 1 + i);
      for (Eigen::Index k = 0; k < n; ++k) target[k] += y[i] * source[k];
    }
  }
}

// Eigenvalues of the 2 × 2 block [[p, q], [r, s]].
LINECLOUD_INLINE_INTO_CLONES void TwoByTwo(double p, double q, double r, double s,
                                           std::complex<double>* e1, std::complex<double>* e2) {
  const double half_trace = 0.5 * (p + s);
  const double half_diff = 0.5 * (p - s);
  const double discriminant = half_diff * half_diff + q * r;
  if (discriminant >= 0) {
    const double root = std::sqrt(discriminant);
    // The larger-magnitude root first, the other from the determinant.
    const double big = half_trace + (half_trace >= 0 ? root : -root);
    const double det = p * s - q * r;
    *e1 = big;
    *e2 = big != 0 ? det / big : half_trace - (half_trace >= 0 ? root : -root);
  } else {
    const double root = std::sqrt(-discriminant);
    *e1 = {half_trace, root};
    *e2 = {half_trace, -root};
  }
}

// Householder reflector P = I − 2vvᵀ/vᵀv with P (x, y[, z]) ∝ e₁; returns
// the normalised v (v₀ = 1) and τ = 2/vᵀv; false when the input is zero.
template <int N>
LINECLOUD_INLINE_INTO_CLONES bool Reflector(const double* in, double* v, double* tau) {
  double norm2 = 0;
  for (int i = 0; i < N; ++i) norm2 += in[i] * in[i];
  if (norm2 == 0) return false;
  const double alpha = in[0] >= 0 ? -std::sqrt(norm2) : std::sqrt(norm2);
  const double v0 = in[0] - alpha;
  v[0] = 1;
  double vtv = 1;
  for (int i = 1; i < N; ++i) {
    v[i] = in[i] / v0;
    vtv += v[i] * v[i];
  }
  *tau = 2 / vtv;
  return true;
}

// Applies P from the left to rows r..r+N−1 (columns c0..c1) and from the
// right to columns r..r+N−1 (rows r0..r1). The right product runs down whole
// columns (contiguous in column-major storage) so that it vectorises.
template <int N>
LINECLOUD_INLINE_INTO_CLONES void ApplyReflector(Eigen::MatrixXd& h, Eigen::Index r,
                                                 const double* v, double tau, Eigen::Index c0,
                                                 Eigen::Index c1, Eigen::Index r0,
                                                 Eigen::Index r1) {
  for (Eigen::Index j = c0; j <= c1; ++j) {
    double* column = &h(r, j);
    double dot = 0;
    for (int i = 0; i < N; ++i) dot += v[i] * column[i];
    dot *= tau;
    for (int i = 0; i < N; ++i) column[i] -= dot * v[i];
  }
  const Eigen::Index len = r1 - r0 + 1;
  if (len <= 0) return;
  double dots[128];
  double* first = &h(r0, r);
  for (Eigen::Index i = 0; i < len; ++i) dots[i] = first[i] * v[0];
  for (int k = 1; k < N; ++k) {
    const double* column = &h(r0, r + k);
    for (Eigen::Index i = 0; i < len; ++i) dots[i] += column[i] * v[k];
  }
  for (int k = 0; k < N; ++k) {
    double* column = &h(r0, r + k);
    const double scale = tau * v[k];
    for (Eigen::Index i = 0; i < len; ++i) column[i] -= dots[i] * scale;
  }
}

}  // namespace

// AVX2/FMA and generic clones (util/multiversion.h).
LINECLOUD_TARGET_CLONES bool EigenvaluesInPlace(Eigen::MatrixXd* matrix,
                                                std::vector<std::complex<double>>* values) {
  values->clear();
  Eigen::MatrixXd& h = *matrix;
  const Eigen::Index n = h.rows();
  if (n > 128) return false;  // block buffers are sized for the solvers' matrices
  if (n == 0 || !h.allFinite()) return n == 0;
  ReduceToHessenberg(matrix);
  constexpr double kEps = std::numeric_limits<double>::epsilon();
  Eigen::Index hi = n - 1;  // active window is rows/columns lo..hi
  int sweeps = 0;
  while (hi >= 0) {
    // Deflate: find the lowest negligible subdiagonal entry.
    Eigen::Index lo = hi;
    while (lo > 0) {
      const double scale = std::abs(h(lo - 1, lo - 1)) + std::abs(h(lo, lo));
      if (std::abs(h(lo, lo - 1)) <= kEps * (scale > 0 ? scale : 1.0)) {
        h(lo, lo - 1) = 0;
        break;
      }
      --lo;
    }
    if (lo == hi) {  // 1 × 1 block
      values->emplace_back(h(hi, hi), 0.0);
      --hi;
      sweeps = 0;
      continue;
    }
    if (lo == hi - 1) {  // 2 × 2 block
      std::complex<double> e1, e2;
      TwoByTwo(h(hi - 1, hi - 1), h(hi - 1, hi), h(hi, hi - 1), h(hi, hi), &e1, &e2);
      values->push_back(e1);
      values->push_back(e2);
      hi -= 2;
      sweeps = 0;
      continue;
    }
    if (++sweeps > 60) return false;
    // Shifts: the eigenvalues of the trailing 2 × 2 block (as sum and
    // product); an exceptional ad-hoc shift every 10 sweeps without deflation.
    double s, t;
    if (sweeps % 10 == 0) {
      const double w = std::abs(h(hi, hi - 1)) + std::abs(h(hi - 1, hi - 2));
      s = 1.5 * w + h(hi, hi);
      t = w * w;
    } else {
      s = h(hi - 1, hi - 1) + h(hi, hi);
      t = h(hi - 1, hi - 1) * h(hi, hi) - h(hi - 1, hi) * h(hi, hi - 1);
    }
    // First column of (H − σ₁)(H − σ₂) restricted to the window.
    double x[3] = {h(lo, lo) * h(lo, lo) + h(lo, lo + 1) * h(lo + 1, lo) - s * h(lo, lo) + t,
                   h(lo + 1, lo) * (h(lo, lo) + h(lo + 1, lo + 1) - s),
                   h(lo + 1, lo) * h(lo + 2, lo + 1)};
    // Chase the bulge down the window.
    for (Eigen::Index k = lo; k + 2 <= hi; ++k) {
      double v[3], tau;
      if (Reflector<3>(x, v, &tau)) {
        const Eigen::Index col0 = std::max(lo, k - 1);
        const Eigen::Index row1 = std::min(hi, k + 3);
        ApplyReflector<3>(h, k, v, tau, col0, hi, lo, row1);
      }
      if (k > lo) {  // the reflector has annihilated the bulge in column k − 1
        h(k + 1, k - 1) = 0;
        h(k + 2, k - 1) = 0;
      }
      x[0] = h(k + 1, k);
      x[1] = h(k + 2, k);
      if (k + 3 <= hi) x[2] = h(k + 3, k);
    }
    double v[2], tau;
    if (Reflector<2>(x, v, &tau)) {
      ApplyReflector<2>(h, hi - 1, v, tau, hi - 2, hi, lo, hi);
    }
    h(hi, hi - 2) = 0;
  }
  return true;
}

}  // namespace linecloud
