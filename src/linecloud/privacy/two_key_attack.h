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

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

struct TwoLiftingsAttack {
  // How the lines were paired: "equal ids", or "crossing" (lines that meet).
  std::string pairing;
  size_t shared_ids = 0;        // ids present in both clouds / pairs of crossing lines
  size_t parallel = 0;          // pairs too close to parallel to cross (same line or shifted copy)
  std::vector<uint64_t> ids;    // the ids (in `a`) of the recovered points
  std::vector<size_t> indices;  // their indices in `a`
  std::vector<Eigen::Vector3d> points;  // midpoint of the two lines' closest points
};

// Pairs whose directions differ by less than `min_angle_rad` are counted as
// parallel: they have no crossing, so nothing is recovered from them.
TwoLiftingsAttack IntersectLinesOfEqualId(const LineCloud& a, const LineCloud& b,
                                          double min_angle_rad = 1e-6);

// Without shared ids (each key also permutes the ids differently), the
// attacker pairs the lines geometrically: two liftings of one point cross
// exactly, while lines of different points miss each other. For each line of
// `a`, the line of `b` nearest to it (line_neighbours.h, then in double
// precision); a pair whose distance is below `max_relative_distance` times the
// anchors' diagonal is intersected. Brute force, O(|a|·|b|), on `threads`.
TwoLiftingsAttack IntersectCrossingLines(const LineCloud& a, const LineCloud& b,
                                         double max_relative_distance = 1e-6, int threads = 0);

// By nearest descriptor: each line of `a` paired with the line of `b` whose
// descriptor is nearest (no ratio test: every line gets a partner), and the
// pair intersected. Versions of one map share descriptors for the same
// physical point whatever their ids. Both clouds need descriptors.
TwoLiftingsAttack IntersectLinesOfNearestDescriptor(const LineCloud& a, const LineCloud& b,
                                                    double min_angle_rad = 1e-6);

// Every pair (line of a, line of b) passing within `tolerance` (model units)
// of each other inside `box`, found through a spatial index of the lines
// (geometry/line_grid.h, up to 512 MB of it), intersected on `threads`
// threads (0: all cores). A point may be recovered several times.
TwoLiftingsAttack IntersectCrossingLinesInBox(const LineCloud& a, const LineCloud& b,
                                              const Eigen::AlignedBox3d& box, double tolerance,
                                              double min_angle_rad = 1e-6, int threads = 0);

// The same within one cloud (pairs of its own lines): two points at one
// place lifted with different directions cross there. Streamed (a dense map
// of a million lines has hundreds of millions of near-crossings):
// found(i, j, midpoint) for each pair i < j, from one thread at a time.
// Returns the number of pairs.
size_t ForEachSelfCrossing(
    const LineCloud& a, const Eigen::AlignedBox3d& box, double tolerance,
    const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&)>& found,
    double min_angle_rad = 1e-6, int threads = 0);

// Equal ids when at least half of a's ids are in b, else crossing lines
// (within 1e-9 of the diagonal for full-precision maps, 1e-6 for compact ones).
TwoLiftingsAttack AttackTwoLiftings(const LineCloud& a, const LineCloud& b, int threads = 0);

}  // namespace linecloud
