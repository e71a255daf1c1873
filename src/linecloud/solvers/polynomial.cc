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

void RealRoots(Poly p, std::vector<double>* roots) {
  double largest = 0;
  for (double c : p) largest = std::max(largest, std::abs(c));
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
  Eigen::MatrixXd companion = Eigen::MatrixXd::Zero(n, n);
  for (int i = 0; i < n; ++i) companion(0, i) = -p[n - 1 - i] / p[n];
  for (int i = 1; i < n; ++i) companion(i, i - 1) = 1.0;
  const Eigen::EigenSolver<Eigen::MatrixXd> solver(companion, false);
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

}  // namespace linecloud::poly
