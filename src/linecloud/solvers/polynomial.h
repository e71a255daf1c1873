// Small dense univariate polynomials (coefficients from the constant term up)
// and real-root finding, for the elimination-based solvers.
#pragma once

#include <vector>

namespace linecloud::poly {

using Poly = std::vector<double>;  // p[k] is the coefficient of x^k

Poly Add(const Poly& a, const Poly& b);
Poly Sub(const Poly& a, const Poly& b);
Poly Mul(const Poly& a, const Poly& b);
Poly Scale(const Poly& a, double s);
double Eval(const Poly& p, double x);
double EvalDerivative(const Poly& p, double x);

// Real roots of p (any degree up to ~20): eigenvalues of the companion
// matrix with a negligible imaginary part, each polished by Newton steps on
// p. Leading coefficients that are negligible relative to the largest one are
// dropped first. Roots are appended to `roots`.
void RealRoots(Poly p, std::vector<double>* roots);

}  // namespace linecloud::poly
