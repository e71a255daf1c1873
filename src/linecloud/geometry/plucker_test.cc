#include "linecloud/geometry/plucker.h"

#include <random>

#include <gtest/gtest.h>

namespace linecloud {
namespace {

Eigen::Vector3d RandomVector(std::mt19937_64& rng, double scale = 1.0) {
  std::normal_distribution<double> n(0.0, scale);
  return {n(rng), n(rng), n(rng)};
}

TEST(PluckerLine, PassesThroughItsPointAndIsValid) {
  std::mt19937_64 rng(3);
  for (int i = 0; i < 1000; ++i) {
    const Eigen::Vector3d x = RandomVector(rng, 100.0);
    const PluckerLine line = PluckerLine::FromPointAndDirection(x, RandomVector(rng));
    EXPECT_TRUE(line.IsValid());
    EXPECT_LT(line.DistanceTo(x), 1e-12 * x.norm());
    EXPECT_LT(line.DistanceTo(line.PointAt(3.7)), 1e-12 * x.norm());
    // The anchor is the closest point to the origin: orthogonal to v.
    EXPECT_LT(std::abs(line.Anchor().dot(line.v)), 1e-12 * x.norm());
  }
}

TEST(PluckerLine, DistanceAndClosestPoint) {
  const PluckerLine z_axis =
      PluckerLine::FromPointAndDirection(Eigen::Vector3d(0, 0, 5), Eigen::Vector3d::UnitZ());
  EXPECT_NEAR(z_axis.DistanceTo(Eigen::Vector3d(3, 4, -7)), 5.0, 1e-15);
  EXPECT_LT((z_axis.ClosestPointTo(Eigen::Vector3d(3, 4, -7)) - Eigen::Vector3d(0, 0, -7)).norm(),
            1e-15);
}

TEST(PluckerLine, OrientationDoesNotMatter) {
  std::mt19937_64 rng(4);
  const Eigen::Vector3d x = RandomVector(rng, 10.0), y = RandomVector(rng, 10.0);
  const PluckerLine a = PluckerLine::FromPointAndDirection(x, RandomVector(rng));
  const PluckerLine flipped(-a.v, -a.w);
  EXPECT_NEAR(a.DistanceTo(y), flipped.DistanceTo(y), 1e-12);
  EXPECT_LT((a.Anchor() - flipped.Anchor()).norm(), 1e-12);
}

TEST(PluckerLine, RigidAndSimilarityTransformsMoveTheLine) {
  std::mt19937_64 rng(5);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d x = RandomVector(rng, 10.0);
    const PluckerLine line = PluckerLine::FromPointAndDirection(x, RandomVector(rng));
    const Eigen::Quaterniond q =
        Eigen::Quaterniond(Eigen::Vector4d(RandomVector(rng).homogeneous())).normalized();
    const Rigid3d b_from_a(q, RandomVector(rng, 5.0));
    const PluckerLine moved = Transform(b_from_a, line);
    EXPECT_TRUE(moved.IsValid(1e-12));
    EXPECT_LT(moved.DistanceTo(b_from_a * x), 1e-11);
    EXPECT_LT(moved.DistanceTo(b_from_a * line.PointAt(2.0)), 1e-11);
    const Sim3d sim(0.1 + 0.05 * i, q, RandomVector(rng, 5.0));
    const PluckerLine scaled = Transform(sim, line);
    EXPECT_TRUE(scaled.IsValid(1e-12));
    EXPECT_LT(scaled.DistanceTo(sim * x), 1e-10);
    EXPECT_LT(scaled.DistanceTo(sim * line.PointAt(-4.0)), 1e-10);
  }
}

TEST(PluckerLine, LineLineDistanceMatchesClosestPoints) {
  std::mt19937_64 rng(6);
  for (int i = 0; i < 500; ++i) {
    const PluckerLine a =
        PluckerLine::FromPointAndDirection(RandomVector(rng, 5.0), RandomVector(rng));
    const PluckerLine b =
        PluckerLine::FromPointAndDirection(RandomVector(rng, 5.0), RandomVector(rng));
    Eigen::Vector3d pa, pb;
    ASSERT_TRUE(ClosestPoints(a, b, &pa, &pb));
    EXPECT_LT(a.DistanceTo(pa), 1e-10);
    EXPECT_LT(b.DistanceTo(pb), 1e-10);
    // The connecting segment is orthogonal to both lines.
    EXPECT_LT(std::abs((pa - pb).dot(a.v)), 1e-9);
    EXPECT_LT(std::abs((pa - pb).dot(b.v)), 1e-9);
    EXPECT_NEAR(LineLineDistance(a, b), (pa - pb).norm(), 1e-9);
  }
  // Intersecting lines have distance 0; parallel lines their offset.
  const Eigen::Vector3d x(1, 2, 3);
  EXPECT_NEAR(LineLineDistance(PluckerLine::FromPointAndDirection(x, {1, 0, 0}),
                               PluckerLine::FromPointAndDirection(x, {0, 1, 1})),
              0.0, 1e-14);
  EXPECT_NEAR(LineLineDistance(
                  PluckerLine::FromPointAndDirection(x, {1, 0, 0}),
                  PluckerLine::FromPointAndDirection(x + Eigen::Vector3d(0, 3, 4), {-1, 0, 0})),
              5.0, 1e-14);
}

// Clipping to a box: the segment's ends lie on the line and on the box's
// faces; a line beside the box misses it.
TEST(Plucker, ClipToBoxGivesTheSegmentInsideTheBox) {
  const Eigen::Vector3d min(-1, -2, -3), max(1, 2, 3);
  const PluckerLine line =
      PluckerLine::FromPointAndDirection({0.5, 0.5, 0.5}, Eigen::Vector3d(1, 2, 0.5));
  Eigen::Vector3d a, b;
  ASSERT_TRUE(ClipToBox(line, min, max, &a, &b));
  for (const Eigen::Vector3d& p : {a, b}) {
    EXPECT_NEAR(line.DistanceTo(p), 0, 1e-12);
    EXPECT_TRUE((p.array() >= min.array() - 1e-12).all() &&
                (p.array() <= max.array() + 1e-12).all());
    EXPECT_NEAR(std::min((p - min).cwiseAbs().minCoeff(), (p - max).cwiseAbs().minCoeff()), 0,
                1e-12);
  }
  // Parallel to an axis: the whole extent along it.
  ASSERT_TRUE(
      ClipToBox(PluckerLine::FromPointAndDirection({0, 0, 0}, {0, 0, 1}), min, max, &a, &b));
  EXPECT_NEAR((b - a).norm(), 6, 1e-12);
  EXPECT_FALSE(
      ClipToBox(PluckerLine::FromPointAndDirection({5, 0, 0}, {0, 1, 0}), min, max, &a, &b));
}

}  // namespace
}  // namespace linecloud
