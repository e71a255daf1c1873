// The two-liftings attack (Speciale et al., "Privacy Preserving Image-Based
// Localization", CVPR 2019, Sec. 3.1: lifting must be permanent): when one
// point is lifted twice with different directions, its two lines cross in the
// point itself. Given two line clouds of one model whose lines carry the same
// ids, the attacker intersects the lines of equal id.
//
// Used by the tests to attack linecloud's own outputs (one point, one line:
// it must recover nothing) and, for a map lifted twice with different keys
// under the same line ids, to show what it gives back.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

struct TwoLiftingsAttack {
  size_t shared_ids = 0;  // ids present in both clouds
  size_t parallel = 0;    // pairs too close to parallel to cross (same line or shifted copy)
  std::vector<uint64_t> ids;             // the ids of the recovered points
  std::vector<Eigen::Vector3d> points;   // midpoint of the two lines' closest points
};

// Pairs whose directions differ by less than `min_angle_rad` are counted as
// parallel: they have no crossing, so nothing is recovered from them.
TwoLiftingsAttack IntersectLinesOfEqualId(const LineCloud& a, const LineCloud& b,
                                          double min_angle_rad = 1e-6);

}  // namespace linecloud
