#include "linecloud/solvers/polynomial.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

namespace linecloud::poly {
namespace {

// The real roots of p by one of the three finders (0: monotone intervals,
// 1: companion matrix, 2: Sturm sequences), sorted.
std::vector<double> SortedRoots(int method, const Poly& p) {
  std::vector<double> roots;
  if (method == 0) {
    MonotoneRealRoots(p, &roots);
  } else if (method == 1) {
    RealRoots(p, &roots);
  } else {
    SturmRealRoots(p, &roots);
  }
  std::sort(roots.begin(), roots.end());
  return roots;
}

// Polynomials built from known roots: k real roots and complex pairs.
TEST(Polynomial, MonotoneCompanionAndSturmRootFindersFindTheKnownRealRoots) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  for (int trial = 0; trial < 2000; ++trial) {
    const int real = static_cast<int>(rng() % 9);
    const int pairs = static_cast<int>(rng() % 3);
    std::vector<double> truth;
    Poly p = {u(rng) + (u(rng) > 0 ? 6.0 : -6.0)};  // non-zero leading factor
    for (int i = 0; i < real; ++i) {
      truth.push_back(u(rng));
      p = Mul(p, {-truth.back(), 1.0});
    }
    for (int i = 0; i < pairs; ++i) {
      const double re = u(rng), im = 0.5 + std::abs(u(rng));
      p = Mul(p, {re * re + im * im, -2 * re, 1.0});
    }
    std::sort(truth.begin(), truth.end());
    // Skip draws with roots closer than 1e-3: ill-conditioned for any method.
    bool separated = true;
    for (size_t i = 1; i < truth.size(); ++i) separated &= truth[i] - truth[i - 1] > 1e-3;
    if (!separated) continue;
    for (int method = 0; method < 3; ++method) {
      const std::vector<double> roots = SortedRoots(method, p);
      ASSERT_EQ(roots.size(), truth.size()) << "method " << method << " trial " << trial;
      for (size_t i = 0; i < roots.size(); ++i) {
        EXPECT_NEAR(roots[i], truth[i], 1e-7 * std::max(1.0, std::abs(truth[i])));
      }
    }
  }
}

// Roots far from 1 (|x| ~ 50–300, as the quaternion ratios of near-180°
// rotations give): the constant term is ~10¹⁸ times the leading one, which
// must not be taken for a negligible leading coefficient. A genuinely
// negligible one (a root near 10¹⁸ next to roots of size 1) is still dropped.
TEST(Polynomial, LargeRootsKeepTheLeadingTermAndRootsAtInfinityAreDropped) {
  const std::vector<double> truth = {-311.8, -305.1, -256.7, -250.0, -153.9, -147.1, -98.8, -92.0};
  Poly p = {-1.0};
  for (double r : truth) p = Mul(p, {-r, 1.0});
  for (int method = 0; method < 3; ++method) {
    const std::vector<double> roots = SortedRoots(method, p);
    ASSERT_EQ(roots.size(), truth.size()) << "method " << method;
    for (size_t i = 0; i < roots.size(); ++i) EXPECT_NEAR(roots[i], truth[i], 1e-9 * 300);
  }
  // (1e-18 x + 1)(x − 1)(x + 2): the root at −10¹⁸ is "at infinity".
  const Poly q = Mul(Mul(Poly{1.0, 1e-18}, Poly{-1.0, 1.0}), Poly{2.0, 1.0});
  for (int method = 0; method < 3; ++method) {
    const std::vector<double> roots = SortedRoots(method, q);
    ASSERT_EQ(roots.size(), 2u) << "method " << method;
    EXPECT_NEAR(roots[0], -2.0, 1e-12);
    EXPECT_NEAR(roots[1], 1.0, 1e-12);
  }
}

// A root near zero next to a root of size one: (x + 1)(x + 10⁻²⁰). The
// polynomial without its leading term has its root near 10⁻²⁰, but the root
// −1 is not "at infinity" and must not be dropped with the leading term.
TEST(Polynomial, ATinyRootDoesNotMakeTheLeadingTermNegligible) {
  const Poly p = Mul(Poly{1.0, 1.0}, Poly{1e-20, 1.0});
  for (int method = 0; method < 3; ++method) {
    const std::vector<double> roots = SortedRoots(method, p);
    ASSERT_EQ(roots.size(), 2u) << "method " << method;
    EXPECT_NEAR(roots[0], -1.0, 1e-14) << "method " << method;
    EXPECT_NEAR(roots[1], -1e-20, 1e-30) << "method " << method;
  }
}

TEST(Polynomial, SturmDegenerateInputs) {
  std::vector<double> roots;
  SturmRealRoots(Poly{}, &roots);
  SturmRealRoots(Poly{0.0, 0.0}, &roots);
  SturmRealRoots(Poly{3.0}, &roots);
  EXPECT_TRUE(roots.empty());
  SturmRealRoots(Poly{-2.0, 1.0}, &roots);
  ASSERT_EQ(roots.size(), 1u);
  EXPECT_DOUBLE_EQ(roots[0], 2.0);
  roots.clear();
  SturmRealRoots(Poly{1.0, 0.0, 1.0}, &roots);  // x² + 1
  EXPECT_TRUE(roots.empty());
  SturmRealRoots(Poly{std::nan(""), 1.0}, &roots);
  EXPECT_TRUE(roots.empty());
  // (x − 1)² (x + 2): the double root once, the simple root exactly.
  SturmRealRoots(Mul(Mul(Poly{-1.0, 1.0}, Poly{-1.0, 1.0}), Poly{2.0, 1.0}), &roots);
  std::sort(roots.begin(), roots.end());
  ASSERT_EQ(roots.size(), 2u);
  EXPECT_NEAR(roots[0], -2.0, 1e-12);
  EXPECT_NEAR(roots[1], 1.0, 1e-6);
  // x (x − 1)(x + 2): the root 0 lies on the first split point, exactly.
  roots.clear();
  SturmRealRoots(Mul(Mul(Poly{0.0, 1.0}, Poly{-1.0, 1.0}), Poly{2.0, 1.0}), &roots);
  std::sort(roots.begin(), roots.end());
  ASSERT_EQ(roots.size(), 3u);
  EXPECT_NEAR(roots[0], -2.0, 1e-14);
  EXPECT_EQ(roots[1], 0.0);
  EXPECT_NEAR(roots[2], 1.0, 1e-14);
}

// Degree 8 (the solvers' degree) takes a fixed-size Sturm sequence when the
// sequence has all nine members, the general one otherwise; both shapes and
// a root on a split point must give the same answers.
TEST(Polynomial, SturmDegreeEightInBothSequenceShapes) {
  const auto roots_of = [](const Poly& p) {
    std::vector<double> roots;
    SturmRealRoots(p, &roots);
    std::sort(roots.begin(), roots.end());
    return roots;
  };
  const Poly complex_pairs = Mul(Poly{1.0, 0.0, 1.0}, Poly{4.0, 2.0, 1.0});
  // Generic: six simple real roots, one of them 0 (the first split point).
  Poly p = {1.0, 0.0, 1.0};
  for (double r : {0.0, 1.0, -2.0, 3.0, -4.0, 5.0}) p = Mul(p, Poly{-r, 1.0});
  ASSERT_EQ(p.size(), 9u);
  std::vector<double> roots = roots_of(p);
  ASSERT_EQ(roots.size(), 6u);
  const double expected[6] = {-4.0, -2.0, 0.0, 1.0, 3.0, 5.0};
  for (int i = 0; i < 6; ++i) EXPECT_NEAR(roots[i], expected[i], 1e-12) << i;
  // A double root: the sequence ends at the common factor (general path).
  p = Mul(complex_pairs, Mul(Mul(Poly{-1.0, 1.0}, Poly{-1.0, 1.0}), Poly{2.0, 1.0}));
  p = Mul(p, Poly{-3.0, 1.0});
  ASSERT_EQ(p.size(), 9u);
  roots = roots_of(p);
  ASSERT_EQ(roots.size(), 3u);
  EXPECT_NEAR(roots[0], -2.0, 1e-12);
  EXPECT_NEAR(roots[1], 1.0, 1e-6);
  EXPECT_NEAR(roots[2], 3.0, 1e-12);
  // x⁸ − 1: the members drop several degrees at once (general path).
  roots = roots_of(Poly{-1.0, 0, 0, 0, 0, 0, 0, 0, 1.0});
  ASSERT_EQ(roots.size(), 2u);
  EXPECT_NEAR(roots[0], -1.0, 1e-14);
  EXPECT_NEAR(roots[1], 1.0, 1e-14);
  // A close pair (10⁻⁵ apart) among four real roots: both found (10⁻⁶
  // apart they merge: the remainder falls below the common-factor threshold).
  p = complex_pairs;
  for (double r : {0.5, 0.50001, -1.5, 2.5}) p = Mul(p, Poly{-r, 1.0});
  ASSERT_EQ(p.size(), 9u);
  roots = roots_of(p);
  ASSERT_EQ(roots.size(), 4u);
  EXPECT_NEAR(roots[1], 0.5, 1e-9);
  EXPECT_NEAR(roots[2], 0.50001, 1e-9);
}

TEST(Polynomial, DegenerateInputs) {
  std::vector<double> roots;
  MonotoneRealRoots({}, &roots);
  MonotoneRealRoots({0.0, 0.0}, &roots);
  MonotoneRealRoots({3.0}, &roots);
  EXPECT_TRUE(roots.empty());
  MonotoneRealRoots({-2.0, 1.0}, &roots);
  ASSERT_EQ(roots.size(), 1u);
  EXPECT_DOUBLE_EQ(roots[0], 2.0);
  roots.clear();
  MonotoneRealRoots({1.0, 0.0, 1.0}, &roots);  // x² + 1
  EXPECT_TRUE(roots.empty());
  MonotoneRealRoots({std::nan(""), 1.0}, &roots);
  for (double r : roots) EXPECT_TRUE(std::isfinite(r));
}

}  // namespace
}  // namespace linecloud::poly
