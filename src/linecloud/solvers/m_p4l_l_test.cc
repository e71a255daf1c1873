#include "linecloud/solvers/m_p4l_l.h"

#include <algorithm>
#include <random>

#include <gtest/gtest.h>

namespace linecloud {
namespace {

// Coefficients on (1, x, y, z, x², xy, xz, y², yz, z²) of (a·p − b)(c·p − d).
Eigen::Matrix<double, 1, 10> ProductOfPlanes(const Eigen::Vector3d& a, double b,
                                             const Eigen::Vector3d& c, double d) {
  Eigen::Matrix<double, 1, 10> q;
  q << b * d, -(a.x() * d + c.x() * b), -(a.y() * d + c.y() * b), -(a.z() * d + c.z() * b),
      a.x() * c.x(), a.x() * c.y() + a.y() * c.x(), a.x() * c.z() + a.z() * c.x(), a.y() * c.y(),
      a.y() * c.z() + a.z() * c.y(), a.z() * c.z();
  return q;
}

// Three pairs of planes meet in 8 known points; random combinations of the
// three quadrics hide that structure but keep the points.
TEST(IntersectThreeQuadrics, FindsTheEightKnownIntersections) {
  std::mt19937_64 rng(5);
  std::normal_distribution<double> n(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    std::array<Eigen::Vector3d, 3> normal;
    std::array<std::array<double, 2>, 3> offset;
    Eigen::Matrix<double, 3, 10> quadrics;
    for (int k = 0; k < 3; ++k) {
      normal[k] = Eigen::Vector3d(n(rng), n(rng), n(rng));
      offset[k] = {n(rng), n(rng) + 3.0};
      quadrics.row(k) = ProductOfPlanes(normal[k], offset[k][0], normal[k], offset[k][1]);
    }
    Eigen::Matrix3d mix = 2 * Eigen::Matrix3d::Identity();
    for (int k = 0; k < 9; ++k) mix(k / 3, k % 3) += 0.5 * n(rng);
    quadrics = mix * quadrics;
    std::vector<Eigen::Vector3d> roots;
    IntersectThreeQuadrics(quadrics, &roots);
    Eigen::Matrix3d planes;
    planes << normal[0].transpose(), normal[1].transpose(), normal[2].transpose();
    int matched = 0;
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3d rhs(offset[0][corner & 1], offset[1][(corner >> 1) & 1],
                                offset[2][(corner >> 2) & 1]);
      const Eigen::Vector3d point = planes.lu().solve(rhs);
      const bool found = std::any_of(roots.begin(), roots.end(), [&](const auto& r) {
        return (r - point).norm() < 1e-8 * std::max(1.0, point.norm());
      });
      matched += found;
    }
    EXPECT_EQ(matched, 8) << "trial " << trial;
    EXPECT_EQ(roots.size(), 8u) << "trial " << trial;
  }
}

// A quadric without x², xy, y² terms makes the hidden-variable elimination's
// (x², xy, y²) block singular (so is the elimination template's): solved
// after a generic rotation of (x, y, z), the eight intersections are found.
TEST(IntersectThreeQuadrics, FindsTheIntersectionsWhenTheLeadingBlockIsSingular) {
  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  int found_all = 0;
  constexpr int kTrials = 100;
  for (int trial = 0; trial < kTrials; ++trial) {
    std::array<Eigen::Vector3d, 3> first, second;
    std::array<std::array<double, 2>, 3> offset;
    Eigen::Matrix<double, 3, 10> quadrics;
    for (int k = 0; k < 3; ++k) {
      first[k] = Eigen::Vector3d(n(rng), n(rng), n(rng));
      second[k] = Eigen::Vector3d(n(rng), n(rng), n(rng));
      offset[k] = {n(rng), n(rng) + 3.0};
    }
    first[0] = Eigen::Vector3d(0, 0, 1);  // (z − b)(c·p − d): no x², xy, y²
    for (int k = 0; k < 3; ++k) {
      quadrics.row(k) = ProductOfPlanes(first[k], offset[k][0], second[k], offset[k][1]);
    }
    quadrics.row(1) += 0.7 * quadrics.row(0);
    quadrics.row(2) -= 0.4 * quadrics.row(0);
    std::vector<Eigen::Vector3d> roots;
    IntersectThreeQuadrics(quadrics, &roots);
    int matched = 0;
    for (int corner = 0; corner < 8; ++corner) {
      Eigen::Matrix3d planes;
      Eigen::Vector3d rhs;
      for (int k = 0; k < 3; ++k) {
        const bool use_second = (corner >> k) & 1;
        planes.row(k) = (use_second ? second[k] : first[k]).transpose();
        rhs[k] = offset[k][use_second ? 1 : 0];
      }
      const Eigen::Vector3d point = planes.lu().solve(rhs);
      matched += std::any_of(roots.begin(), roots.end(), [&](const auto& r) {
        return (r - point).norm() < 1e-7 * std::max(1.0, point.norm());
      });
    }
    found_all += matched == 8;
  }
  EXPECT_GE(found_all, kTrials * 95 / 100);
}

// No real intersection: x² + 1 = 0 combined with anything.
TEST(IntersectThreeQuadrics, ReturnsNothingWithoutRealIntersections) {
  Eigen::Matrix<double, 3, 10> quadrics;
  quadrics << 1, 0, 0, 0, 1, 0, 0, 0, 0, 0,  // x² + 1
      -1, 0, 0, 0, 0, 0, 0, 1, 0, 0,         // y² − 1
      -4, 0, 0, 0, 0, 0, 0, 0, 0, 1;         // z² − 4
  const Eigen::Matrix3d mix = (Eigen::Matrix3d() << 1, 2, 0.5, -1, 1, 3, 2, 0, 1).finished();
  std::vector<Eigen::Vector3d> roots;
  EXPECT_EQ(IntersectThreeQuadrics(mix * quadrics, &roots), 0);
}

}  // namespace
}  // namespace linecloud
