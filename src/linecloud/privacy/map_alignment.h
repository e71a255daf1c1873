// Two published maps of one place, brought into one frame from the files
// alone, as an attacker holding both would (issue [rebuild]): a second map in
// another frame (another owner's, a rebuild) is no protection once aligned.
//
// 1. The density attack (Chelani, Kahl, Sattler, CVPR 2021; density_attack.h)
//    estimates a point on each line of both maps.
// 2. Lines are paired by descriptor (mutual nearest, ratio test): versions of
//    one place share descriptors for one physical point.
// 3. A similarity through the pairs' estimated points, robust (triples of
//    Umeyama's fit, similarity_fit.h), tolerance a share of the scene.
// 4. Refined on the lines themselves: the two lines of one physical point
//    cross there, so the closest points of each pair's lines are fitted
//    again (a point-to-point step on the closest points, as ICP does),
//    keeping the pairs that pass within a shrinking tolerance.
#pragma once

#include <string>

#include "linecloud/geometry/rigid3.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/privacy/density_attack.h"

namespace linecloud {

struct MapAlignmentOptions {
  double max_ratio = 0.8;   // descriptor pairs for the fit
  double tolerance = 0.02;  // share of a's diagonal (density estimates)
  int ransac_iterations = 2000;
  int refine_iterations = 30;
  double min_crossing_angle_deg = 5;  // pairs closer to parallel do not refine
  uint64_t seed = 7;

  void Check() const;
};

struct MapAlignment {
  Sim3d a_from_b;
  bool aligned = false;
  std::string why_not;  // when not aligned
  size_t descriptor_pairs = 0;
  size_t ransac_inliers = 0;        // pairs whose estimated points agree
  size_t refined_pairs = 0;         // pairs whose lines cross within the final tolerance
  double median_line_distance = 0;  // of those, share of a's diagonal
};

// The estimated points are `density_a` / `density_b` (RunDensityAttack on
// each map). Both maps need descriptors of one size.
MapAlignment AlignMaps(const LineCloud& a, const LineCloud& b, const DensityAttackResult& density_a,
                       const DensityAttackResult& density_b, const MapAlignmentOptions& options);

// `b`'s lines moved into a's frame.
LineCloud TransformedCloud(const LineCloud& b, const Sim3d& a_from_b);

}  // namespace linecloud
