#include "linecloud/synthetic/match_scores.h"

#include <array>

namespace linecloud {
namespace {

// Counts per bin [0.05 b, 0.05 (b + 1)), measured as match_scores.h says.
constexpr double kBinWidth = 0.05;
constexpr std::array<double, 16> kInliers = {44,   30,   165,  671,  1552, 3189, 4546, 5681,
                                             6391, 6641, 6661, 6490, 6102, 5662, 5141, 4639};
constexpr std::array<double, 16> kOutliers = {1,  0,  0,   1,   6,   5,   13,  26,
                                              44, 69, 112, 170, 266, 398, 743, 1652};

}  // namespace

double DrawMatchRatio(bool inlier, std::mt19937_64& rng) {
  const std::array<double, 16>& counts = inlier ? kInliers : kOutliers;
  std::discrete_distribution<int> bin(counts.begin(), counts.end());
  std::uniform_real_distribution<double> within(0.0, 1.0);
  const int b = bin(rng);
  return kBinWidth * (b + within(rng));
}

}  // namespace linecloud
