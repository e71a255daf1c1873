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

// Real roots of p (degree up to 24): eigenvalues of the companion
// matrix with a negligible imaginary part, each polished by Newton steps on
// p. Leading coefficients that are negligible relative to the largest one are
// dropped first. Roots are appended to `roots`.
void RealRoots(Poly p, std::vector<double>* roots);

// The same roots without an eigen-decomposition: the real roots of p' (found
// recursively down to degree 1) cut the line into intervals on which p is
// monotonic, each holding at most one root, found by Newton steps kept inside
// a sign-change bracket; a critical point where p vanishes (a double root) is
// reported too. Roots lie within the Cauchy bound, and by Gauss–Lucas so do
// the derivatives' roots. Degree up to 24.
void MonotoneRealRoots(const Poly& p, std::vector<double>* roots);

// The same roots by Sturm sequences (fixed-size arrays, degree up to 16): the
// sequence p, p', −rem(·, ·), … counts the real roots in any interval; the
// Fujiwara-bounded interval is bisected until each piece holds one root,
// which bracketed Halley steps then polish to full precision. Multiple roots
// are reported once. Writes the roots to `roots` (room for `degree` values)
// and returns how many; `coefficients` has degree + 1 entries, constant first.
int SturmRealRoots(const double* coefficients, int degree, double* roots);
void SturmRealRoots(const Poly& p, std::vector<double>* roots);

}  // namespace linecloud::poly
