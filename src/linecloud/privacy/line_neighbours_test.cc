#include "linecloud/privacy/line_neighbours.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <random>

namespace linecloud {
namespace {

// Lines through points of a thin slab (a surface, as SfM points are), far
// from the origin, with random directions.
LineArrays SlabLines(size_t n, uint64_t seed, std::vector<Eigen::Vector3d>* points = nullptr) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::normal_distribution<double> g(0.0, 1.0);
  const Eigen::Vector3d offset(3e4, -2e4, 50);
  std::vector<PluckerLine> lines;
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = offset + Eigen::Vector3d(u(rng), u(rng), 0.1 * u(rng));
    if (points) points->push_back(x - offset);
    lines.push_back(PluckerLine::FromPointAndDirection(x, Eigen::Vector3d(g(rng), g(rng), g(rng))));
  }
  return MakeLineArrays(lines, offset);
}

// The coarse votes through the grid against every pair: each line's votes
// are those of the lines within the radius meeting it inside the box, the
// nearest k of them up to the width of a distance bin (1/32 of the radius).
TEST(NeighbourGrid, CoarseVotesAreTheNearestPairsEveryPairFinds) {
  const size_t n = 2500, k = 40;
  const LineArrays a = SlabLines(n, 3);
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-4, -4, -1), Eigen::Vector3d(4, 4, 1));
  const double r = 0.15;
  const NeighbourGrid grid(a, box, r, size_t{1} << 22);
  const NeighbourGrid::LineVotes votes = grid.CoarseVotes(k, 2);
  ASSERT_EQ(votes.starts.size(), n + 1);
  size_t complete = 0, with_votes = 0;
  for (size_t i = 0; i < n; ++i) {
    // Every pair: (distance, t along line i) of the lines within r meeting inside the box.
    std::vector<std::pair<double, double>> brute;
    for (size_t j = 0; j < n; ++j) {
      if (j == i) continue;
      const double c = a.v[i].dot(a.v[j]), s2 = 1 - c * c;
      if (s2 <= 1e-4) continue;
      const Eigen::Vector3d rq = a.q[j] - a.q[i];
      const double d = std::abs(rq.dot(a.v[i].cross(a.v[j]))) / std::sqrt(s2);
      const double ti = (rq.dot(a.v[i]) - c * rq.dot(a.v[j])) / s2;
      const double tj = (c * rq.dot(a.v[i]) - rq.dot(a.v[j])) / s2;
      const Eigen::Vector3d mid = 0.5 * (a.q[i] + ti * a.v[i] + a.q[j] + tj * a.v[j]);
      if (d <= r && box.contains(mid)) brute.push_back({d, ti});
    }
    std::sort(brute.begin(), brute.end());
    std::vector<float> got(votes.t.begin() + votes.starts[i],
                           votes.t.begin() + votes.starts[i + 1]);
    with_votes += !got.empty();
    // Each vote is one of the pairs (to float precision)...
    for (const float t : got) {
      const bool found = std::any_of(brute.begin(), brute.end(),
                                     [&](const auto& b) { return std::abs(b.second - t) < 1e-3; });
      EXPECT_TRUE(found) << "line " << i << ": vote " << t << " is no pair's";
    }
    // ... and the nearest k are all there (those within a bin of the k-th may
    // fall either side of a cell's or the box's edge in float).
    const size_t want = std::min(k, brute.size());
    if (want == 0) {
      complete += got.empty();
      continue;
    }
    const double kth = brute[want - 1].first;
    size_t present = 0, needed = 0;
    for (const auto& b : brute) {
      if (b.first > kth - r / 32) break;
      ++needed;
      present += std::any_of(got.begin(), got.end(),
                             [&](float t) { return std::abs(t - b.second) < 1e-3; });
    }
    complete += present == needed && got.size() >= want;
  }
  EXPECT_GT(with_votes, n * 3 / 4);
  EXPECT_GE(complete, n * 99 / 100) << "of " << n << " lines";
}

// Lines crowding through one spot (a crafted map) would each keep a vote
// per crowding line: they keep none and are searched over every line
// instead, so the votes stay O(n k).
TEST(NeighbourGrid, CrowdedLinesKeepNoVotes) {
  std::vector<PluckerLine> lines;
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  std::normal_distribution<double> g(0.0, 1.0);
  for (int i = 0; i < 4000; ++i) {
    const Eigen::Vector3d x =
        i < 1500 ? Eigen::Vector3d(1, 1, 0.1) + 1e-7 * Eigen::Vector3d(g(rng), g(rng), g(rng))
                 : Eigen::Vector3d(u(rng), u(rng), 0.1 * u(rng));
    lines.push_back(PluckerLine::FromPointAndDirection(x, Eigen::Vector3d(g(rng), g(rng), g(rng))));
  }
  const LineArrays a = MakeLineArrays(lines, Eigen::Vector3d::Zero());
  const size_t k = 20;
  const NeighbourGrid grid(
      a, Eigen::AlignedBox3d(Eigen::Vector3d(-6, -6, -2), Eigen::Vector3d(6, 6, 2)), 0.1,
      size_t{1} << 22);
  const NeighbourGrid::LineVotes votes = grid.CoarseVotes(k, 2);
  EXPECT_LE(votes.t.size(), lines.size() * (4 * k + 64));
  size_t crowded = 0;
  for (size_t i = 0; i < 1500; ++i) crowded += votes.exact[i];
  EXPECT_EQ(crowded, 1500u);
}

// The point searches: exactly the nearest within the radius, other than the
// line's or point's own.
TEST(NeighbourGrid, PointSearchesFindWhatEveryPairFinds) {
  const size_t n = 3000, k = 25;
  std::vector<Eigen::Vector3d> centred;
  const LineArrays a = SlabLines(n, 5, &centred);
  const Eigen::AlignedBox3d box(Eigen::Vector3d(-6, -6, -2), Eigen::Vector3d(6, 6, 2));
  NeighbourGrid grid(a, box, 0.05, size_t{1} << 22);
  const PointArrays p = MakePointArrays(centred);
  grid.SetPoints(&p);
  const double r = 0.6;
  NeighbourGrid::Buffers buffers;
  SelectBuffers select;
  std::vector<float> d2(n);
  std::vector<uint32_t> got, want;
  const auto within = [&](std::vector<uint32_t>* ids) {
    std::erase_if(*ids, [&](uint32_t j) { return !(d2[j] <= r * r); });
    std::sort(ids->begin(), ids->end());
  };
  for (size_t i = 0; i < n; i += 7) {
    LineToPointsSq(a, i, p, d2.data());
    d2[i] = std::numeric_limits<float>::infinity();
    // The k nearest by brute force, then only those within r (all of them
    // when fewer than k are).
    SmallestK(d2, k, &select, &want);
    within(&want);
    grid.NearestPoints(i, k, r, &buffers, &got);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << "points near line " << i;
    PointToLinesSq(p, i, a, d2.data());
    d2[i] = std::numeric_limits<float>::infinity();
    SmallestK(d2, k, &select, &want);
    within(&want);
    grid.NearestLinesToPoint(i, k, r, &buffers, &got);
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << "lines near point " << i;
  }
}

}  // namespace
}  // namespace linecloud
