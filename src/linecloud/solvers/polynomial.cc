#include "linecloud/solvers/polynomial.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Eigenvalues>

namespace linecloud::poly {

Poly Add(const Poly& a, const Poly& b) {
  Poly r(std::max(a.size(), b.size()), 0.0);
  for (size_t i = 0; i < a.size(); ++i) r[i] += a[i];
  for (size_t i = 0; i < b.size(); ++i) r[i] += b[i];
  return r;
}

Poly Sub(const Poly& a, const Poly& b) { return Add(a, Scale(b, -1.0)); }

Poly Mul(const Poly& a, const Poly& b) {
  if (a.empty() || b.empty()) return {};
  Poly r(a.size() + b.size() - 1, 0.0);
  for (size_t i = 0; i < a.size(); ++i) {
    for (size_t j = 0; j < b.size(); ++j) r[i + j] += a[i] * b[j];
  }
  return r;
}

Poly Scale(const Poly& a, double s) {
  Poly r = a;
  for (double& c : r) c *= s;
  return r;
}

double Eval(const Poly& p, double x) {
  double v = 0;
  for (size_t i = p.size(); i-- > 0;) v = v * x + p[i];
  return v;
}

double EvalDerivative(const Poly& p, double x) {
  double v = 0;
  for (size_t i = p.size(); i-- > 1;) v = v * x + static_cast<double>(i) * p[i];
  return v;
}

namespace {
constexpr int kMaxCompanion = 24;
}  // namespace

void RealRoots(Poly p, std::vector<double>* roots) {
  double largest = 0;
  for (double c : p) {
    if (!std::isfinite(c)) return;
    largest = std::max(largest, std::abs(c));
  }
  if (!(largest > 0) || !std::isfinite(largest)) return;
  while (!p.empty() && std::abs(p.back()) <= 1e-14 * largest) p.pop_back();
  // Roots at zero.
  size_t zeros = 0;
  while (zeros < p.size() && p[zeros] == 0.0) ++zeros;
  if (zeros > 0) {
    roots->push_back(0.0);
    p.erase(p.begin(), p.begin() + zeros);
  }
  const int n = static_cast<int>(p.size()) - 1;
  if (n < 1) return;
  if (n == 1) {
    roots->push_back(-p[0] / p[1]);
    return;
  }
  if (n > kMaxCompanion) return;
  // Dynamic size with a fixed upper bound: lives on the stack.
  using Companion = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCompanion,
                                  kMaxCompanion>;
  Companion companion = Companion::Zero(n, n);
  for (int i = 0; i < n; ++i) companion(0, i) = -p[n - 1 - i] / p[n];
  for (int i = 1; i < n; ++i) companion(i, i - 1) = 1.0;
  const Eigen::EigenSolver<Companion> solver(companion, false);
  if (solver.info() != Eigen::Success) return;
  const auto& values = solver.eigenvalues();
  for (int i = 0; i < n; ++i) {
    const std::complex<double> z = values[i];
    if (std::abs(z.imag()) > 1e-6 * std::max(1.0, std::abs(z.real()))) continue;
    double x = z.real();
    for (int it = 0; it < 4; ++it) {  // Newton polish
      const double d = EvalDerivative(p, x);
      if (d == 0) break;
      const double step = Eval(p, x) / d;
      if (!std::isfinite(step)) break;
      x -= step;
    }
    if (std::isfinite(x)) roots->push_back(x);
  }
}

namespace {

constexpr int kMaxMonotone = 24;

double EvalRaw(const double* p, int n, double x) {
  double v = p[n];
  for (int i = n - 1; i >= 0; --i) v = v * x + p[i];
  return v;
}

// Σ |p_i| |x|^i: the scale of p(x)'s rounding error.
double AbsEval(const double* p, int n, double x) {
  const double ax = std::abs(x);
  double v = std::abs(p[n]);
  for (int i = n - 1; i >= 0; --i) v = v * ax + std::abs(p[i]);
  return v;
}

double EvalRawDerivative(const double* p, int n, double x) {
  double v = n * p[n];
  for (int i = n - 1; i >= 1; --i) v = v * x + i * p[i];
  return v;
}

// The root of p in (lo, hi) given p(lo) = flo and p(hi) of the opposite
// sign: Newton steps kept inside the shrinking bracket, bisection otherwise.
double BracketedRoot(const double* p, int n, double lo, double hi, double flo,
                     double tolerance) {
  double x = 0.5 * (lo + hi);
  for (int it = 0; it < 200; ++it) {
    const double f = EvalRaw(p, n, x);
    if (f == 0) return x;
    if ((f > 0) == (flo > 0)) {
      lo = x;
      flo = f;
    } else {
      hi = x;
    }
    const double d = EvalRawDerivative(p, n, x);
    double next = d != 0 ? x - f / d : 0.5 * (lo + hi);
    if (!(next > lo && next < hi)) next = 0.5 * (lo + hi);
    const double size = tolerance * std::max(1.0, std::abs(x));
    if (std::abs(next - x) <= size || hi - lo <= size) return next;
    x = next;
  }
  return x;
}

// Sorted real roots of p (degree n) in [-bound, bound], given the sorted
// roots of p' in `critical`.
int RootsBetween(const double* p, int n, double bound, const double* critical,
                 int num_critical, double tolerance, double* out) {
  int count = 0;
  double lo = -bound;
  double flo = EvalRaw(p, n, lo);
  for (int k = 0; k <= num_critical; ++k) {
    const double hi = k < num_critical ? critical[k] : bound;
    const double fhi = EvalRaw(p, n, hi);
    if (flo != 0 && fhi != 0 && (flo > 0) != (fhi > 0)) {
      out[count++] = BracketedRoot(p, n, lo, hi, flo, tolerance);
    } else if (k < num_critical && std::abs(fhi) <= 1e-12 * AbsEval(p, n, hi)) {
      out[count++] = hi;  // touching (double) root at a critical point
    }
    lo = hi;
    flo = fhi;
  }
  return count;
}

}  // namespace

void MonotoneRealRoots(const Poly& input, std::vector<double>* roots) {
  double largest = 0;
  for (double c : input) {
    if (!std::isfinite(c)) return;
    largest = std::max(largest, std::abs(c));
  }
  if (!(largest > 0) || !std::isfinite(largest)) return;
  int n = static_cast<int>(input.size()) - 1;
  while (n >= 0 && std::abs(input[n]) <= 1e-14 * largest) --n;
  if (n < 1) return;
  if (n > kMaxMonotone) {
    RealRoots(input, roots);
    return;
  }
  // Derivatives: d[k] is the k-th derivative, degree n − k (monic scaling
  // does not matter for roots).
  double d[kMaxMonotone + 1][kMaxMonotone + 1];
  for (int i = 0; i <= n; ++i) d[0][i] = input[i] / input[n];
  for (int k = 1; k < n; ++k) {
    const int m = n - k;
    for (int i = 0; i <= m; ++i) d[k][i] = d[k - 1][i + 1] * (i + 1) / (m + 1);
  }
  // Fujiwara's bound: every root has |x| <= 2 max_k |a_{n−k}|^{1/k}
  // (monic; the constant term's share halved).
  double bound = 0;
  for (int k = 1; k <= n; ++k) {
    const double a = std::abs(d[0][n - k]) * (k == n ? 0.5 : 1.0);
    if (a > 0) bound = std::max(bound, std::pow(a, 1.0 / k));
  }
  bound = 2.0 * bound * (1.0 + 1e-12) + 1e-300;
  // Up from the linear (n−1)-th derivative.
  double current[kMaxMonotone], next[kMaxMonotone];
  int num = 1;
  current[0] = -d[n - 1][0] / d[n - 1][1];
  for (int k = n - 2; k >= 0; --k) {
    // Derivatives' roots only bound intervals: 1e-10 is plenty there.
    num = RootsBetween(d[k], n - k, bound, current, num, k == 0 ? 4e-16 : 1e-10, next);
    std::copy(next, next + num, current);
  }
  roots->insert(roots->end(), current, current + num);
}

}  // namespace linecloud::poly
