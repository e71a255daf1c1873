#include "linecloud/geometry/line_grid.h"

#include <algorithm>
#include <random>
#include <set>

#include <gtest/gtest.h>

namespace linecloud {
namespace {

// Lines through points of a box far from the origin (precision), some pairs
// made to cross exactly or nearly (the case the attacks look for).
std::vector<PluckerLine> RandomLines(std::mt19937_64& rng, size_t n, const Eigen::Vector3d& offset,
                                     std::vector<Eigen::Vector3d>* points) {
  std::uniform_real_distribution<double> u(-10.0, 10.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<PluckerLine> lines;
  for (size_t i = 0; i < n; ++i) {
    Eigen::Vector3d x(u(rng), u(rng), 0.2 * u(rng));
    if (i % 7 == 1) x = (*points)[i - 1] + Eigen::Vector3d(g(rng), g(rng), g(rng)) * 1e-4;
    points->push_back(x);
    lines.push_back(
        PluckerLine::FromPointAndDirection(x + offset, Eigen::Vector3d(g(rng), g(rng), g(rng))));
  }
  return lines;
}

TEST(LineGrid, FindsExactlyThePairsAndLinesABruteForceFinds) {
  std::mt19937_64 rng(11);
  const Eigen::Vector3d offset(4e5, -3e5, 120);  // map coordinates far from the origin
  std::vector<Eigen::Vector3d> points;
  const std::vector<PluckerLine> lines = RandomLines(rng, 1500, offset, &points);
  Eigen::AlignedBox3d box(offset + Eigen::Vector3d(-10, -10, -2),
                          offset + Eigen::Vector3d(10, 10, 2));
  const double radius = 0.01;
  const LineGrid grid(lines, box, radius);
  ASSERT_GT(grid.entries(), lines.size());

  std::set<std::pair<uint32_t, uint32_t>> found;
  grid.CrossingPairs(1e-6, {}, [&](uint32_t i, uint32_t j, const Eigen::Vector3d& mid, double d) {
    EXPECT_LT(i, j);
    EXPECT_LE(d, radius);
    EXPECT_TRUE(box.contains(mid));
    EXPECT_TRUE(found.insert({i, j}).second) << "pair reported twice";
  });
  std::set<std::pair<uint32_t, uint32_t>> expected;
  for (uint32_t i = 0; i < lines.size(); ++i) {
    for (uint32_t j = i + 1; j < lines.size(); ++j) {
      Eigen::Vector3d a, b;
      if (!ClosestPoints(lines[i], lines[j], &a, &b)) continue;
      if ((a - b).norm() <= radius * (1 - 1e-9) && box.contains(0.5 * (a + b)))
        expected.insert({i, j});
    }
  }
  EXPECT_GE(expected.size(), 1500u / 7 - 5);  // the planted near-crossings at least
  for (const auto& p : expected) EXPECT_TRUE(found.count(p)) << p.first << " " << p.second;

  // Lines near each point: those of the point itself and of its planted twin.
  std::vector<uint32_t> near;
  for (size_t k = 0; k < points.size(); k += 13) {
    grid.LinesNear(points[k] + offset, &near);
    std::vector<uint32_t> brute;
    for (uint32_t i = 0; i < lines.size(); ++i) {
      if (lines[i].DistanceTo(points[k] + offset) <= radius) brute.push_back(i);
    }
    std::sort(near.begin(), near.end());
    EXPECT_EQ(near, brute) << "point " << k;
    EXPECT_TRUE(std::binary_search(near.begin(), near.end(), static_cast<uint32_t>(k)));
  }
}

TEST(LineGrid, GroupsKeepOnlyPairsAcrossAndParallelLinesNeverPair) {
  // Two copies of one line (groups 0 and 1) are parallel: no crossing. A third
  // line crossing it is paired only with the line of the other group.
  const Eigen::Vector3d x(1, 2, 3);
  const std::vector<PluckerLine> lines = {
      PluckerLine::FromPointAndDirection(x, Eigen::Vector3d(1, 0, 0)),
      PluckerLine::FromPointAndDirection(x, Eigen::Vector3d(1, 0, 0)),
      PluckerLine::FromPointAndDirection(x, Eigen::Vector3d(0, 1, 0))};
  const std::vector<uint8_t> group = {0, 1, 0};
  const LineGrid grid(lines, Eigen::AlignedBox3d(Eigen::Vector3d::Zero(), Eigen::Vector3d(5, 5, 5)),
                      1e-3);
  std::vector<std::pair<uint32_t, uint32_t>> pairs;
  grid.CrossingPairs(1e-6, group, [&](uint32_t i, uint32_t j, const Eigen::Vector3d& mid, double) {
    pairs.push_back({i, j});
    EXPECT_LT((mid - x).norm(), 1e-12);
  });
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(1u, 2u));
}

TEST(LineGrid, RobustBoxLeavesStrayPointsOut) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 1000; ++i) points.emplace_back(i % 10, (i / 10) % 10, i / 100);
  points.emplace_back(1e6, 0, 0);
  const Eigen::AlignedBox3d box = RobustBox(points, 0.005, 0.0);
  EXPECT_LT(box.max().x(), 10);
  EXPECT_GE(box.min().x(), 0);
}

}  // namespace
}  // namespace linecloud
