#include "linecloud/estimation/ransac.h"

#include <random>

#include <Eigen/Dense>

#include <gtest/gtest.h>

namespace linecloud {
namespace {

// A 2D line y = a x + b from two points: the smallest estimator that
// exercises every part of the concept.
struct LineEstimator {
  using Model = Eigen::Vector2d;  // (a, b)
  std::vector<Eigen::Vector2d> points;
  int refinements = 0;

  int num_data() const { return static_cast<int>(points.size()); }
  int sample_size() const { return 2; }
  int generate_models(std::span<const int> sample, std::vector<Model>* out) {
    out->clear();
    const Eigen::Vector2d& p = points[sample[0]];
    const Eigen::Vector2d& q = points[sample[1]];
    if (std::abs(q.x() - p.x()) < 1e-12) return 0;
    const double a = (q.y() - p.y()) / (q.x() - p.x());
    out->emplace_back(a, p.y() - a * p.x());
    return 1;
  }
  double Residual(const Model& m, const Eigen::Vector2d& p) const {
    return p.y() - (m[0] * p.x() + m[1]);
  }
  double score_model(const Model& m, double threshold, double /*bound*/, int* inliers) const {
    double score = 0;
    *inliers = 0;
    for (const auto& p : points) {
      const double r2 = std::pow(Residual(m, p), 2);
      *inliers += r2 < threshold * threshold;
      score += std::min(r2, threshold * threshold);
    }
    return score;
  }
  void refine_model(Model* m, double threshold) {
    ++refinements;
    // Least squares on the inliers.
    Eigen::Matrix2d a = Eigen::Matrix2d::Zero();
    Eigen::Vector2d b = Eigen::Vector2d::Zero();
    for (const auto& p : points) {
      if (std::abs(Residual(*m, p)) >= threshold) continue;
      const Eigen::Vector2d row(p.x(), 1.0);
      a += row * row.transpose();
      b += row * p.y();
    }
    *m = a.ldlt().solve(b);
  }
  void inliers(const Model& m, double threshold, std::vector<char>* mask) const {
    mask->clear();
    for (const auto& p : points) mask->push_back(std::abs(Residual(m, p)) < threshold);
  }
};

LineEstimator NoisyLine(int n, double inlier_ratio, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-10, 10);
  std::normal_distribution<double> noise(0, 0.01);
  LineEstimator e;
  for (int i = 0; i < n; ++i) {
    const double x = u(rng);
    e.points.emplace_back(x, i < inlier_ratio * n ? 0.5 * x - 2 + noise(rng) : u(rng));
  }
  return e;
}

TEST(Ransac, FindsTheLineAmongHalfOutliersAndStopsAdaptively) {
  LineEstimator e = NoisyLine(400, 0.5, 3);
  RansacOptions options;
  options.max_error = 0.05;
  options.seed = 17;
  const RansacResult<Eigen::Vector2d> r = Ransac(e, options);
  ASSERT_TRUE(r.success);
  EXPECT_NEAR(r.model[0], 0.5, 1e-3);
  EXPECT_NEAR(r.model[1], -2.0, 1e-2);
  EXPECT_NEAR(r.stats.inlier_ratio, 0.5, 0.01);
  // 50 % inliers, 2-point samples, 0.9999: ceil(log(1e-4) / log(0.75)) = 33.
  EXPECT_LE(r.stats.iterations, 40);
  EXPECT_GE(r.stats.iterations, options.min_iterations);
  EXPECT_GT(e.refinements, 0);
  EXPECT_EQ(r.stats.local_optimizations, e.refinements);
  EXPECT_DOUBLE_EQ(r.stats.mean_solutions, 1.0);
  int marked = 0;
  for (char c : r.inlier_mask) marked += c;
  EXPECT_EQ(marked, r.stats.num_inliers);
}

TEST(Ransac, SameSeedSameResultOtherSeedOtherSamples) {
  RansacOptions options;
  options.max_error = 0.05;
  options.local_optimization = false;
  options.seed = 5;
  LineEstimator a = NoisyLine(300, 0.3, 1), b = NoisyLine(300, 0.3, 1);
  const auto ra = Ransac(a, options), rb = Ransac(b, options);
  EXPECT_EQ(ra.model, rb.model);
  EXPECT_EQ(ra.stats.iterations, rb.stats.iterations);
  options.seed = 6;
  const auto rc = Ransac(a, options);
  EXPECT_TRUE(rc.success);
  EXPECT_NE(ra.model, rc.model);  // another all-inlier sample, another noisy fit
}

TEST(Ransac, TooFewDataOrBadOptions) {
  LineEstimator e = NoisyLine(1, 1.0, 2);
  EXPECT_FALSE(Ransac(e, RansacOptions{}).success);
  RansacOptions bad;
  bad.max_error = -1;
  EXPECT_THROW(Ransac(e, bad), Error);
  bad = RansacOptions{};
  bad.confidence = 1.0;
  EXPECT_THROW(Ransac(e, bad), Error);
}

TEST(Ransac, RequiredIterationsMatchesTheFormula) {
  EXPECT_EQ(RequiredIterations(0.5, 2, 0.9999, 10000), 33);
  EXPECT_EQ(RequiredIterations(1.0, 3, 0.99, 10000), 0);
  EXPECT_EQ(RequiredIterations(0.0, 3, 0.99, 500), 500);
  EXPECT_EQ(RequiredIterations(0.1, 6, 0.9999, 10000), 10000);
}

}  // namespace
}  // namespace linecloud
