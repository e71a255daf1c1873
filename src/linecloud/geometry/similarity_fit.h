// Similarity transforms between two point sets with known correspondences:
// dst ≈ s R src + t.
//
// FitSimilarity is the least-squares solution (Umeyama, "Least-squares
// estimation of transformation parameters between two point patterns",
// TPAMI 1991; Eigen's implementation). FitSimilarityRobust draws triples
// (a fixed seed: the same input gives the same transform), keeps the one
// with the most pairs within `tolerance`, and refits on those.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// Needs ≥ 3 pairs not all on one line; returns scale 0 otherwise.
Sim3d FitSimilarity(std::span<const Eigen::Vector3d> src, std::span<const Eigen::Vector3d> dst);

struct RobustSimilarityFit {
  Sim3d dst_from_src;
  std::vector<uint32_t> inliers;  // indices of the pairs within tolerance
};

// `tolerance` in dst units. Fewer than 3 pairs: the identity, no inliers.
RobustSimilarityFit FitSimilarityRobust(std::span<const Eigen::Vector3d> src,
                                        std::span<const Eigen::Vector3d> dst, double tolerance,
                                        int iterations = 300, uint64_t seed = 7);

}  // namespace linecloud
