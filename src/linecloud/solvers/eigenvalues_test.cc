#include "linecloud/solvers/eigenvalues.h"

#include <algorithm>
#include <random>

#include <Eigen/Eigenvalues>
#include <Eigen/LU>
#include <gtest/gtest.h>

namespace linecloud {
namespace {

// Largest distance from an expected eigenvalue to the nearest computed one,
// relative to max(1, |λ|); also checks the count.
double WorstMatch(const std::vector<std::complex<double>>& expected,
                  const std::vector<std::complex<double>>& computed) {
  EXPECT_EQ(expected.size(), computed.size());
  double worst = 0;
  for (const auto& e : expected) {
    double best = 1e300;
    for (const auto& c : computed) best = std::min(best, std::abs(e - c));
    worst = std::max(worst, best / std::max(1.0, std::abs(e)));
  }
  return worst;
}

TEST(Eigenvalues, KnownSpectrumUnderASimilarity) {
  // V diag(blocks) V⁻¹ with real eigenvalues and complex pairs a ± bi.
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int n : {1, 2, 3, 5, 17, 64}) {
    Eigen::MatrixXd d = Eigen::MatrixXd::Zero(n, n);
    std::vector<std::complex<double>> expected;
    int i = 0;
    while (i < n) {
      if (i + 1 < n && (i % 3 == 1)) {
        const double a = 3 * u(rng), b = 0.1 + std::abs(u(rng));
        d(i, i) = a, d(i, i + 1) = b, d(i + 1, i) = -b, d(i + 1, i + 1) = a;
        expected.emplace_back(a, b);
        expected.emplace_back(a, -b);
        i += 2;
      } else {
        d(i, i) = 5 * u(rng);
        expected.emplace_back(d(i, i), 0);
        ++i;
      }
    }
    Eigen::MatrixXd v = Eigen::MatrixXd::Identity(n, n) + 0.3 * Eigen::MatrixXd::Random(n, n);
    Eigen::MatrixXd a = v * d * v.inverse();
    std::vector<std::complex<double>> computed;
    ASSERT_TRUE(EigenvaluesInPlace(&a, &computed)) << n;
    EXPECT_LT(WorstMatch(expected, computed), 1e-9) << n;
  }
}

TEST(Eigenvalues, AgreesWithEigenOnRandomAndBadlyScaledMatrices) {
  std::srand(11);
  for (int trial = 0; trial < 100; ++trial) {
    const int n = 2 + trial % 66;
    Eigen::MatrixXd a = Eigen::MatrixXd::Random(n, n);
    if (trial % 3 == 0) {
      for (int i = 0; i < n; ++i) a.row(i) *= std::pow(10.0, i % 5 - 2);
    }
    const Eigen::EigenSolver<Eigen::MatrixXd> reference(a, false);
    std::vector<std::complex<double>> expected(reference.eigenvalues().begin(),
                                               reference.eigenvalues().end());
    std::vector<std::complex<double>> computed;
    ASSERT_TRUE(EigenvaluesInPlace(&a, &computed)) << trial;
    EXPECT_LT(WorstMatch(expected, computed), 1e-9) << trial;
  }
}

TEST(Eigenvalues, StructuredAndInvalidInput) {
  std::vector<std::complex<double>> computed;
  Eigen::MatrixXd zero = Eigen::MatrixXd::Zero(6, 6);
  ASSERT_TRUE(EigenvaluesInPlace(&zero, &computed));
  EXPECT_EQ(computed.size(), 6u);
  for (const auto& c : computed) EXPECT_EQ(std::abs(c), 0.0);
  // A cyclic shift: the 8th roots of unity.
  Eigen::MatrixXd shift = Eigen::MatrixXd::Zero(8, 8);
  for (int i = 0; i < 8; ++i) shift(i, (i + 1) % 8) = 1;
  ASSERT_TRUE(EigenvaluesInPlace(&shift, &computed));
  ASSERT_EQ(computed.size(), 8u);
  for (const auto& c : computed) EXPECT_NEAR(std::abs(c), 1.0, 1e-12);
  Eigen::MatrixXd bad = Eigen::MatrixXd::Identity(4, 4);
  bad(2, 1) = std::nan("");
  EXPECT_FALSE(EigenvaluesInPlace(&bad, &computed));
}

}  // namespace
}  // namespace linecloud
