#include "linecloud/geometry/rigid3.h"

#include <random>

#include <gtest/gtest.h>

namespace linecloud {
namespace {

Rigid3d RandomRigid(std::mt19937_64& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  return Rigid3d(Eigen::Quaterniond(n(rng), n(rng), n(rng), n(rng)).normalized(),
                 Eigen::Vector3d(n(rng), n(rng), n(rng)));
}

TEST(Rigid3d, QuaternionIsWxyz) {
  // 90° about z: (w, x, y, z) = (cos 45°, 0, 0, sin 45°) maps x to y.
  const Rigid3d r(Eigen::Quaterniond(std::sqrt(0.5), 0, 0, std::sqrt(0.5)),
                  Eigen::Vector3d::Zero());
  EXPECT_LT((r * Eigen::Vector3d::UnitX() - Eigen::Vector3d::UnitY()).norm(), 1e-15);
}

TEST(Rigid3d, InverseAndComposition) {
  std::mt19937_64 rng(1);
  for (int i = 0; i < 100; ++i) {
    const Rigid3d b_from_a = RandomRigid(rng), c_from_b = RandomRigid(rng);
    const Eigen::Vector3d x(0.3 * i, -1.0, 2.0);
    EXPECT_LT((b_from_a.Inverse() * (b_from_a * x) - x).norm(), 1e-12);
    EXPECT_LT(((c_from_b * b_from_a) * x - c_from_b * (b_from_a * x)).norm(), 1e-12);
    // Centre maps to the origin of the target frame.
    EXPECT_LT((b_from_a * b_from_a.Center()).norm(), 1e-12);
  }
}

TEST(Sim3d, InverseAndComposition) {
  std::mt19937_64 rng(2);
  for (int i = 0; i < 100; ++i) {
    const Rigid3d r1 = RandomRigid(rng), r2 = RandomRigid(rng);
    const Sim3d b_from_a(0.1 + i * 0.1, r1.rotation, r1.translation);
    const Sim3d c_from_b(2.5, r2.rotation, r2.translation);
    const Eigen::Vector3d x(1.0, 2.0, -0.5 * i);
    EXPECT_LT((b_from_a.Inverse() * (b_from_a * x) - x).norm(), 1e-11);
    EXPECT_LT(((c_from_b * b_from_a) * x - c_from_b * (b_from_a * x)).norm(), 1e-11);
  }
}

}  // namespace
}  // namespace linecloud
