#include "linecloud/solvers/polynomial.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <limits>

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

// The smallest e with a^(1/k) ≤ 2^e (up to one ulp: a < 2^(ilogb(a)+1)), for
// a > 0, k ≥ 1: root bounds as powers of two, without pow.
int RootBoundExponent(double a, int k) {
  const int e = std::ilogb(a) + 1;
  return e >= 0 ? (e + k - 1) / k : -((-e) / k);
}

// Degree of c[0..degree] after dropping leading coefficients that only
// carry roots "at infinity": c_n is negligible when |c_n| ρ ≤ 1e-14 |c_{n−1}|,
// i.e. when the root it adds, near −c_{n−1} / c_n, lies beyond 10¹⁴ ρ, with ρ
// (≥ 1) Fujiwara's bound on the roots of the polynomial without its leading
// term. Comparing raw coefficients would drop the leading term of, e.g., a
// degree-8 polynomial whose roots are all near 100 (its constant term is
// ~10¹⁶ times larger); ρ ≥ 1 keeps the root −1 of (x + 1)(x + 10⁻²⁰), whose
// other root alone would make ρ tiny.
int EffectiveDegree(const double* c, int degree) {
  int n = degree;
  while (n >= 0 && c[n] == 0) --n;
  while (n >= 1) {
    const double top = std::abs(c[n - 1]);
    if (!(top > 0)) break;  // the next term vanishes: keep c[n]
    const double lead = std::abs(c[n]) / top;
    if (lead > 1e-14) break;  // kept whatever ρ ≥ 1 is
    // ρ = 2^rho_exponent, within a factor 4 of Fujiwara's bound, at least 1.
    int rho_exponent = -1;
    for (int k = 0; k < n - 1; ++k) {
      const double a = std::abs(c[k]) / top;
      if (a > 0) rho_exponent = std::max(rho_exponent, RootBoundExponent(a, n - 1 - k));
    }
    if (std::ldexp(lead, rho_exponent + 1) > 1e-14) break;
    --n;
    while (n >= 0 && c[n] == 0) --n;
  }
  return n;
}
}  // namespace

void RealRoots(Poly p, std::vector<double>* roots) {
  double largest = 0;
  for (double c : p) {
    if (!std::isfinite(c)) return;
    largest = std::max(largest, std::abs(c));
  }
  if (!(largest > 0) || !std::isfinite(largest)) return;
  p.resize(static_cast<size_t>(EffectiveDegree(p.data(), static_cast<int>(p.size()) - 1) + 1));
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
  using Companion =
      Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, kMaxCompanion, kMaxCompanion>;
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
double BracketedRoot(const double* p, int n, double lo, double hi, double flo, double tolerance) {
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
int RootsBetween(const double* p, int n, double bound, const double* critical, int num_critical,
                 double tolerance, double* out) {
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
  const int n = EffectiveDegree(input.data(), static_cast<int>(input.size()) - 1);
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

namespace {

constexpr int kMaxSturm = 16;

// Thresholds shared by both Sturm sequence builders below (members scaled to
// unit largest coefficient): a remainder no larger than kSturmCommonFactor
// means the common factor of p and p′ was reached (a multiple root), and a
// leading coefficient below kSturmNegligibleLead is dropped.
constexpr double kSturmCommonFactor = 1e-13;
constexpr double kSturmNegligibleLead = 1e-14;

// A Sturm sequence of any shape: members of falling degree, each scaled to
// unit largest coefficient; a member may drop more than one degree, and the
// sequence ends early at a common factor (a multiple root).
struct SturmSequence {
  static constexpr int kFixedDegree = 0;   // degree known only at run time
  double p[kMaxSturm + 1][kMaxSturm + 1];  // p[k][i]: coefficient i of member k
  int degree[kMaxSturm + 1];
  int size = 0;

  const double* Polynomial() const { return p[0]; }
  int Degree() const { return degree[0]; }

  // Sign changes along the sequence at x (zeros skipped); p₀(x) in *value.
  int SignChanges(double x, double* value) const {
    int changes = 0;
    double previous = 0;
    for (int k = 0; k < size; ++k) {
      double v = p[k][degree[k]];
      for (int i = degree[k] - 1; i >= 0; --i) v = v * x + p[k][i];
      if (k == 0) *value = v;
      if (v == 0) continue;
      if (previous != 0 && (v > 0) != (previous > 0)) ++changes;
      previous = v;
    }
    return changes;
  }

  // Sign changes at +∞ (direction 1) or −∞ (direction −1), from the leading
  // coefficients; equal to those at ±bound, beyond which p has no root.
  int SignChangesAtInfinity(int direction) const {
    int changes = 0;
    bool previous_positive = false;
    for (int k = 0; k < size; ++k) {
      const bool positive = (p[k][degree[k]] > 0) != (direction < 0 && degree[k] % 2 == 1);
      if (k > 0 && positive != previous_positive) ++changes;
      previous_positive = positive;
    }
    return changes;
  }

  double Value(double x) const {
    double v = p[0][degree[0]];
    for (int i = degree[0] - 1; i >= 0; --i) v = v * x + p[0][i];
    return v;
  }
};

// Scales a member to unit largest coefficient (a positive factor keeps the
// sign pattern) and drops negligible leading coefficients; false when zero.
bool Normalise(double* c, int* degree, double reference) {
  double largest = 0;
  for (int i = 0; i <= *degree; ++i) largest = std::max(largest, std::abs(c[i]));
  if (!(largest > kSturmCommonFactor * reference)) return false;
  const double inverse = 1.0 / largest;
  for (int i = 0; i <= *degree; ++i) c[i] *= inverse;
  while (*degree > 0 && std::abs(c[*degree]) < kSturmNegligibleLead) --*degree;
  return true;
}

void BuildSturm(const double* monic, int n, SturmSequence* s) {
  std::copy(monic, monic + n + 1, s->p[0]);
  s->degree[0] = n;
  for (int i = 1; i <= n; ++i) s->p[1][i - 1] = i * monic[i];
  s->degree[1] = n - 1;
  s->size = 2;
  double reference = 0;
  for (int i = 0; i <= n; ++i) reference = std::max(reference, std::abs(monic[i]));
  Normalise(s->p[0], &s->degree[0], reference);
  Normalise(s->p[1], &s->degree[1], 1.0);
  while (s->degree[s->size - 1] > 0 && s->size <= kMaxSturm) {
    // r = a mod b, computed in the next member's place.
    const double* b = s->p[s->size - 1];
    const int db = s->degree[s->size - 1];
    const double inverse_lead = 1.0 / b[db];
    double* r = s->p[s->size];
    int dr = s->degree[s->size - 2];
    std::copy(s->p[s->size - 2], s->p[s->size - 2] + dr + 1, r);
    while (dr >= db) {
      const double q = r[dr] * inverse_lead;
      for (int i = 0; i < db; ++i) r[dr - db + i] -= q * b[i];
      --dr;
    }
    if (dr < 0) break;
    // The next member is −r / max|r| (a positive scale keeps the signs);
    // a remainder at rounding level means the gcd was reached (multiple roots).
    double largest = 0;
    for (int i = 0; i <= dr; ++i) largest = std::max(largest, std::abs(r[i]));
    if (!(largest > kSturmCommonFactor)) break;
    const double scale = -1.0 / largest;
    for (int i = 0; i <= dr; ++i) r[i] *= scale;
    while (dr > 0 && std::abs(r[dr]) < kSturmNegligibleLead) --dr;
    s->degree[s->size] = dr;
    ++s->size;
  }
}

// The generic Sturm sequence of a degree-N polynomial — N + 1 members of
// degrees N, N − 1, …, 0 — with the degrees known at compile time, so that
// evaluating it is straight-line code (the members' Horner chains run side by
// side) and counting sign changes has no branches. Same arithmetic and
// thresholds as BuildSturm; Build() reports false for any other shape (a
// degree drop, an early common factor), which the general sequence handles.
template <int N>
struct FixedSturmSequence {
  static constexpr int kFixedDegree = N;
  double m[N + 1][N + 1];  // m[k][i]: coefficient i of member k (degree N − k)

  const double* Polynomial() const { return m[0]; }
  int Degree() const { return N; }

  bool Build(const double* monic) {
    double largest = 0;
    for (int i = 0; i <= N; ++i) largest = std::max(largest, std::abs(monic[i]));
    double inverse = 1.0 / largest;
    for (int i = 0; i <= N; ++i) m[0][i] = monic[i] * inverse;
    largest = 0;
    for (int i = 1; i <= N; ++i) largest = std::max(largest, i * std::abs(m[0][i]));
    if (!(largest > kSturmCommonFactor)) return false;
    inverse = 1.0 / largest;
    for (int i = 1; i <= N; ++i) m[1][i - 1] = i * m[0][i] * inverse;
    if (std::abs(m[1][N - 1]) < kSturmNegligibleLead) return false;
#pragma GCC unroll 16
    for (int k = 1; k < N; ++k) {
      // −rem(m[k − 1], m[k]): two steps of long division by a member of
      // degree db = N − k, leaving a remainder of degree db − 1.
      const double* a = m[k - 1];
      const double* b = m[k];
      const int db = N - k;
      double r[N + 1];
      for (int i = 0; i <= db + 1; ++i) r[i] = a[i];
      const double inverse_lead = 1.0 / b[db];
      double q = r[db + 1] * inverse_lead;
      for (int i = 0; i < db; ++i) r[i + 1] -= q * b[i];
      q = r[db] * inverse_lead;
      for (int i = 0; i < db; ++i) r[i] -= q * b[i];
      largest = 0;
      for (int i = 0; i < db; ++i) largest = std::max(largest, std::abs(r[i]));
      if (!(largest > kSturmCommonFactor)) return false;
      const double scale = -1.0 / largest;
      for (int i = 0; i < db; ++i) m[k + 1][i] = r[i] * scale;
      if (std::abs(m[k + 1][db - 1]) < kSturmNegligibleLead) return false;
    }
    return true;
  }

  // As SturmSequence::SignChanges. A member k ≥ 1 that vanishes at x may
  // count as either sign (its neighbours have opposite signs there); only
  // p₀(x) = 0 must be left out.
  int SignChanges(double x, double* value) const {
    double v[N + 1];
#pragma GCC unroll 16
    for (int k = 0; k <= N; ++k) {
      double s = m[k][N - k];
#pragma GCC unroll 16
      for (int i = N - k - 1; i >= 0; --i) s = s * x + m[k][i];
      v[k] = s;
    }
    *value = v[0];
    int changes = v[0] != 0 && std::signbit(v[0]) != std::signbit(v[1]);
#pragma GCC unroll 16
    for (int k = 1; k < N; ++k) changes += std::signbit(v[k]) != std::signbit(v[k + 1]);
    return changes;
  }

  int SignChangesAtInfinity(int direction) const {
    int changes = 0;
    for (int k = 0; k < N; ++k) {
      // Leading coefficients of degrees N − k and N − k − 1: their signs
      // at −∞ differ by one extra factor −1.
      const bool a = m[k][N - k] > 0, b = m[k + 1][N - k - 1] > 0;
      changes += (a != b) != (direction < 0);
    }
    return changes;
  }

  double Value(double x) const {
    double v = m[0][N];
#pragma GCC unroll 16
    for (int i = N - 1; i >= 0; --i) v = v * x + m[0][i];
    return v;
  }
};

// x^K for K a power of two, by squaring.
template <int K>
inline double PowerOfTwoPower(double x) {
  if constexpr (K == 1) {
    return x;
  } else {
    const double half = PowerOfTwoPower<K / 2>(x);
    return half * half;
  }
}

// Σ c_i x^i for i = 0..D by Estrin's scheme: with K the largest power of two
// ≤ D, p = (c_0 + … + c_{K−1} x^{K−1}) + x^K (c_K + … + c_D x^{D−K}), both
// halves split the same way — pairs c_{2j} + c_{2j+1} x, then pairs of those
// with x², x⁴, …: a dependency chain of ~log₂ D multiply-adds instead of
// Horner's D (the three chains of a Halley step are then short enough to
// overlap).
template <int D>
inline double Estrin(const double* c, double x) {
  if constexpr (D == 0) {
    return c[0];
  } else if constexpr (D == 1) {
    return c[0] + c[1] * x;
  } else {
    constexpr int kHalf = static_cast<int>(std::bit_floor(static_cast<unsigned>(D)));
    return Estrin<kHalf - 1>(c, x) + PowerOfTwoPower<kHalf>(x) * Estrin<D - kHalf>(c + kHalf, x);
  }
}

// p(x), p′(x) and p″(x) / 2 of p (degree n, or N when N > 0; then `dp` and
// `ddp` hold the coefficients of p′ and p″ / 2).
template <int N>
struct PolishEvaluator {
  double dp[N], ddp[N - 1];
  const double* p;
  explicit PolishEvaluator(const double* coefficients, int) : p(coefficients) {
    for (int i = 0; i < N; ++i) dp[i] = (i + 1) * p[i + 1];
    for (int i = 0; i < N - 1; ++i) ddp[i] = 0.5 * (i + 1) * (i + 2) * p[i + 2];
  }
  void operator()(double x, double* f, double* d1, double* d2) const {
    *f = Estrin<N>(p, x);
    *d1 = Estrin<N - 1>(dp, x);
    *d2 = Estrin<N - 2>(ddp, x);
  }
};
template <>
struct PolishEvaluator<0> {
  const double* p;
  int n;
  PolishEvaluator(const double* coefficients, int degree) : p(coefficients), n(degree) {}
  // One Horner pass whose three chains run side by side.
  void operator()(double x, double* f, double* d1, double* d2) const {
    double v = p[n], e1 = 0, e2 = 0;
    for (int i = n - 1; i >= 0; --i) {
      e2 = e2 * x + e1;
      e1 = e1 * x + v;
      v = v * x + p[i];
    }
    *f = v;
    *d1 = e1;
    *d2 = e2;
  }
};

// The single root of p in (a, b), where p changes sign (p(a) = fa, p(b) = fb):
// Halley steps, x − f / (f′ − f f″ / (2 f′)), cubically convergent, safeguarded
// as Newton is in "rtsafe" (Press et al., Numerical Recipes, §9.4) — a step
// that would leave the bracket, or that does not at least halve the previous
// one, is replaced by a bisection (geometric while the bracket spans orders of
// magnitude: far from its roots a degree-n polynomial makes Newton advance by
// only ~1/n of the distance per step). f, f′ and f″ / 2 are evaluated
// together, so a Halley step costs little more than a Newton step and saves
// about two of them per root.
template <typename Evaluator>
double PolishRoot(const Evaluator& evaluate, double a, double b, double fa, double fb) {
  const auto split = [](double lo, double hi) {
    if (lo > 0 && hi > 8 * lo) return std::sqrt(lo * hi);
    if (hi < 0 && lo < 8 * hi) return -std::sqrt(lo * hi);
    return 0.5 * (lo + hi);
  };
  // Start from the secant (regula falsi) point of a narrow bracket.
  double x = split(a, b);
  if (b - a < std::max(std::abs(a), std::abs(b))) {
    const double secant = a - fa * (b - a) / (fb - fa);
    if (secant > a && secant < b) x = secant;
  }
  double previous_step = b - a, step = previous_step;
  double last_halley = 0;  // the previous iteration's Halley step, 0 after a bisection
  for (int iteration = 0; iteration < 200; ++iteration) {
    double f, d1, d2;  // p(x), p′(x), p″(x) / 2
    evaluate(x, &f, &d1, &d2);
    if (f == 0) return x;
    // Keep the sign change inside [a, b].
    if ((f > 0) == (fa > 0)) {
      a = x;
      fa = f;
    } else {
      b = x;
    }
    const double delta = -f * d1 / (d1 * d1 - f * d2);
    const double halley = x + delta;
    const double scale = std::max(1.0, std::abs(x));
    const double tolerance = 2e-15 * scale;
    // Converged when a step is at rounding level (the result is then as good
    // as double allows; one more step would only oscillate), or when the
    // steps shrink cubically (|δₖ| ≈ C |δₖ₋₁|³) and the next one,
    // C |δₖ|³ = |δₖ|⁴ / |δₖ₋₁|³, would be. Tested before the bracket check: x
    // is itself an end of the updated bracket.
    if (std::abs(delta) <= tolerance) return halley;
    if (last_halley != 0 && std::abs(delta) < 1e-3 * std::abs(last_halley) && halley > a &&
        halley < b) {
      const double ratio = delta / last_halley;
      if (std::abs(delta) * ratio * ratio * ratio <= 1e-16 * scale) return halley;
    }
    if (halley > a && halley < b && 2 * std::abs(delta) <= std::abs(previous_step)) {
      previous_step = step;
      step = delta;
      last_halley = delta;
      x = halley;
    } else {
      const double mid = split(a, b);
      previous_step = step;
      step = mid - x;
      last_halley = 0;
      x = mid;
    }
    if (b - a <= 2 * tolerance) return x;
  }
  return x;
}

// The real roots of the sequence's first member in [−bound, bound]: the
// interval is bisected on the sign-change counts until each piece holds one
// root, which PolishRoot then finds. Returns how many were written to
// `roots`, or −1 when a fixed sequence meets a root of even multiplicity
// (left to the general sequence).
template <typename Sequence>
int IsolateRoots(const Sequence& sturm, double bound, double* roots) {
  const PolishEvaluator<Sequence::kFixedDegree> evaluate(sturm.Polynomial(), sturm.Degree());
  const int n = sturm.Degree();
  struct Interval {
    double a, b;
    int changes_a, changes_b;
    double fa, fb;  // p at a and at b
  };
  Interval stack[2 * kMaxSturm + 64];
  int top = 0;
  stack[top++] = {-bound,
                  bound,
                  sturm.SignChangesAtInfinity(-1),
                  sturm.SignChangesAtInfinity(1),
                  sturm.Value(-bound),
                  sturm.Value(bound)};
  int count = 0;
  while (top > 0 && count < n) {
    // Fields read one by one (a whole-struct copy here stalled on store
    // forwarding: the pushes below write the same slots).
    --top;
    const Interval iv{stack[top].a,         stack[top].b,  stack[top].changes_a,
                      stack[top].changes_b, stack[top].fa, stack[top].fb};
    const int inside = iv.changes_a - iv.changes_b;
    if (inside <= 0) continue;
    if (inside == 1) {
      if (iv.fb == 0) {  // the one root of (a, b] is b
        roots[count++] = iv.b;
        continue;
      }
      if (iv.fa != 0 && (iv.fa > 0) != (iv.fb > 0)) {
        roots[count++] = PolishRoot(evaluate, iv.a, iv.b, iv.fa, iv.fb);
        continue;
      }
      if constexpr (Sequence::kFixedDegree > 0) return -1;
      // No sign change: a root of even multiplicity; bisect on the counts.
      double a = iv.a, b = iv.b;
      int changes_a = iv.changes_a;
      for (int step = 0; step < 200 && b - a > 1e-14 * std::max(1.0, std::abs(a)); ++step) {
        const double mid = 0.5 * (a + b);
        double unused = 0;
        const int changes_mid = sturm.SignChanges(mid, &unused);
        if (changes_a - changes_mid >= 1) {
          b = mid;
        } else {
          a = mid;
          changes_a = changes_mid;
        }
      }
      roots[count++] = 0.5 * (a + b);
      continue;
    }
    // Split at 0 first, then geometrically while the interval spans orders
    // of magnitude (the Fujiwara bound is often far beyond the roots), else
    // in the middle.
    double mid = 0.5 * (iv.a + iv.b);
    if (iv.a < 0 && iv.b > 0) {
      mid = 0;
    } else {
      const double lo = std::min(std::abs(iv.a), std::abs(iv.b));
      const double hi = std::max(std::abs(iv.a), std::abs(iv.b));
      if (hi > 8 * std::max(lo, 1e-3)) {
        const double geometric = std::sqrt(std::max(lo, 1e-3) * hi);
        mid = iv.a >= 0 ? geometric : -geometric;
      }
    }
    if (iv.b - iv.a <= 1e-14 * std::max(1.0, std::abs(mid))) {
      roots[count++] = mid;  // a cluster or multiple root: reported once
      continue;
    }
    if (top + 2 > static_cast<int>(std::size(stack))) break;
    double f_mid = 0;
    const int changes_mid = sturm.SignChanges(mid, &f_mid);
    stack[top++] = {iv.a, mid, iv.changes_a, changes_mid, iv.fa, f_mid};
    stack[top++] = {mid, iv.b, changes_mid, iv.changes_b, f_mid, iv.fb};
  }
  return count;
}

// Fixed-degree path for n = N, −1 when the sequence is not generic.
template <int N>
int FixedSturmRoots(const double* monic, double bound, double* roots) {
  FixedSturmSequence<N> sturm;
  if (!sturm.Build(monic)) return -1;
  return IsolateRoots(sturm, bound, roots);
}

}  // namespace

int SturmRealRoots(const double* coefficients, int degree, double* roots) {
  double largest = 0;
  for (int i = 0; i <= degree; ++i) {
    if (!std::isfinite(coefficients[i])) return 0;
    largest = std::max(largest, std::abs(coefficients[i]));
  }
  if (!(largest > 0)) return 0;
  const int n = EffectiveDegree(coefficients, degree);
  if (n < 1) return 0;
  if (n > kMaxSturm) {
    std::vector<double> found;
    MonotoneRealRoots(Poly(coefficients, coefficients + degree + 1), &found);
    std::copy(found.begin(), found.end(), roots);
    return static_cast<int>(found.size());
  }
  double monic[kMaxSturm + 1];
  const double inverse_lead = 1.0 / coefficients[n];
  for (int i = 0; i < n; ++i) monic[i] = coefficients[i] * inverse_lead;
  monic[n] = 1;
  if (n == 1) {
    roots[0] = -monic[0];
    return 1;
  }
  // Substitute x = σ ξ with σ a power of two (exact) near the geometric mean
  // of the roots' magnitudes, |a₀ / aₙ|^(1/n): the sequence's members then
  // have coefficients of comparable size, so dropping negligible leading
  // coefficients never removes a real one (roots ~10² would otherwise give
  // coefficients spanning 10¹⁸). The roots are scaled back at the end.
  int lowest = 0;
  while (lowest < n && monic[lowest] == 0) ++lowest;
  const int exponent =
      static_cast<int>(std::lround(std::ilogb(monic[lowest]) / static_cast<double>(n - lowest)));
  if (exponent != 0) {
    // a_i σ^(i−n), by exact multiplications with 2^−exponent (one ldexp each
    // only where a power could leave double's range).
    if (std::abs(exponent) * n < 900) {
      const double factor = std::ldexp(1.0, -exponent);
      double power = 1;
      for (int i = n - 1; i >= 0; --i) {
        power *= factor;
        monic[i] *= power;
      }
    } else {
      for (int i = 0; i < n; ++i) monic[i] = std::ldexp(monic[i], -exponent * (n - i));
    }
  }
  // Fujiwara's bound (as in MonotoneRealRoots), rounded up to a power of two.
  int bound_exponent = std::numeric_limits<int>::min();
  for (int k = 1; k <= n; ++k) {
    const double a = std::abs(monic[n - k]) * (k == n ? 0.5 : 1.0);
    if (a > 0) bound_exponent = std::max(bound_exponent, RootBoundExponent(a, k));
  }
  const double bound = bound_exponent == std::numeric_limits<int>::min()
                           ? 1e-300
                           : std::ldexp(1.0, bound_exponent + 1) * (1.0 + 1e-12);
  // The solvers' degree (8: m-p3P, p4L+u, m-p4L+u, m-P4L+l) gets a
  // fixed-size generic sequence; other degrees, and shapes it cannot
  // represent, go to the general one.
  int count = n == 8 ? FixedSturmRoots<8>(monic, bound, roots) : -1;
  if (count < 0) {
    SturmSequence sturm;
    BuildSturm(monic, n, &sturm);
    count = IsolateRoots(sturm, bound, roots);
  }
  if (exponent != 0) {
    if (std::abs(exponent) < 1000) {
      const double sigma = std::ldexp(1.0, exponent);
      for (int i = 0; i < count; ++i) roots[i] *= sigma;
    } else {
      for (int i = 0; i < count; ++i) roots[i] = std::ldexp(roots[i], exponent);
    }
  }
  return count;
}

void SturmRealRoots(const Poly& p, std::vector<double>* roots) {
  if (p.empty()) return;
  double found[kMaxSturm + 1];
  const int degree = static_cast<int>(p.size()) - 1;
  if (degree > kMaxSturm) {
    MonotoneRealRoots(p, roots);
    return;
  }
  const int count = SturmRealRoots(p.data(), degree, found);
  roots->insert(roots->end(), found, found + count);
}

}  // namespace linecloud::poly
