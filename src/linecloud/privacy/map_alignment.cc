#include "linecloud/privacy/map_alignment.h"

#include <algorithm>
#include <cmath>

#include "linecloud/features/matching.h"
#include "linecloud/geometry/similarity_fit.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/util/error.h"

namespace linecloud {

void MapAlignmentOptions::Check() const {
  if (!(max_ratio > 0 && max_ratio <= 1)) Fail("alignment: max_ratio {} not in (0, 1]", max_ratio);
  if (!(tolerance > 0 && tolerance < 1)) Fail("alignment: tolerance {} not in (0, 1)", tolerance);
  if (ransac_iterations < 1 || refine_iterations < 0) {
    Fail("alignment: {} RANSAC / {} refinement iterations", ransac_iterations, refine_iterations);
  }
  if (!(min_crossing_angle_deg >= 0 && min_crossing_angle_deg < 90)) {
    Fail("alignment: min_crossing_angle_deg {} not in [0, 90)", min_crossing_angle_deg);
  }
}

LineCloud TransformedCloud(const LineCloud& b, const Sim3d& a_from_b) {
  LineCloud out = b;
  for (PluckerLine& l : out.lines) l = Transform(a_from_b, l);
  return out;
}

MapAlignment AlignMaps(const LineCloud& a, const LineCloud& b, const DensityAttackResult& density_a,
                       const DensityAttackResult& density_b, const MapAlignmentOptions& o) {
  o.Check();
  MapAlignment r;
  if (!a.has_descriptors() || !b.has_descriptors() || a.descriptor_dim != b.descriptor_dim) {
    r.why_not = "the maps carry no descriptors of one size to pair their lines by";
    return r;
  }
  if (density_a.points.size() != a.size() || density_b.points.size() != b.size()) {
    Fail("alignment: {} / {} density estimates for {} / {} lines", density_a.points.size(),
         density_b.points.size(), a.size(), b.size());
  }
  DescriptorMatchOptions m;
  m.dim = a.descriptor_dim;
  m.max_ratio = o.max_ratio;
  m.max_distance = 3.2;
  m.cross_check = true;
  const std::vector<DescriptorMatch> pairs = MatchDescriptors(b.descriptors, a.descriptors, m);
  r.descriptor_pairs = pairs.size();
  if (pairs.size() < 3) {
    r.why_not = "fewer than 3 lines pair by descriptor: no common place";
    return r;
  }
  std::vector<Eigen::Vector3d> from_b, to_a;
  for (const DescriptorMatch& p : pairs) {
    from_b.push_back(density_b.points[p.query]);
    to_a.push_back(density_a.points[p.map]);
  }
  const double diagonal = SceneDiagonal(density_a.points);
  const RobustSimilarityFit fit =
      FitSimilarityRobust(from_b, to_a, o.tolerance * diagonal, o.ransac_iterations, o.seed);
  r.ransac_inliers = fit.inliers.size();
  // Chance agreement among wrong pairs stays near a handful; a common place
  // gives hundreds.
  if (fit.inliers.size() < std::max<size_t>(10, pairs.size() / 50)) {
    r.why_not = "the pairs' estimated points agree on no similarity: no common place";
    return r;
  }
  Sim3d t = fit.dst_from_src;
  const double min_sin = std::sin(o.min_crossing_angle_deg * M_PI / 180);
  double tolerance = o.tolerance * diagonal;
  std::vector<Eigen::Vector3d> on_b, on_a;
  std::vector<double> distances;
  for (int iter = 0; iter < o.refine_iterations; ++iter) {
    on_b.clear();
    on_a.clear();
    distances.clear();
    const Sim3d b_from_a = t.Inverse();
    for (const DescriptorMatch& p : pairs) {
      const PluckerLine& la = a.lines[p.map];
      const PluckerLine lb = Transform(t, b.lines[p.query]);
      // Crossing lines: their closest points. Near-parallel ones (a released
      // line published again) have none: the point of b's line nearest to
      // a's estimate, and its foot on a's line.
      Eigen::Vector3d pa, pb;
      if (la.v.cross(lb.v).norm() < min_sin || !ClosestPoints(la, lb, &pa, &pb)) {
        pb = lb.ClosestPointTo(density_a.points[p.map]);
        pa = la.ClosestPointTo(pb);
      }
      const double d = (pa - pb).norm();
      if (!(d <= tolerance)) continue;
      // Near the estimated point only: a pair of unrelated lines crosses
      // somewhere too.
      if ((pa - density_a.points[p.map]).norm() > 5 * o.tolerance * diagonal) continue;
      on_b.push_back(b_from_a * pb);
      on_a.push_back(pa);
      distances.push_back(d);
    }
    if (on_b.size() < 3) break;
    const Sim3d next = FitSimilarity(on_b, on_a);
    if (!(next.scale > 0)) break;
    t = next;
    r.refined_pairs = on_b.size();
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    r.median_line_distance = distances[distances.size() / 2] / diagonal;
    // The tolerance follows the fit down to three times its median residual.
    tolerance = std::max(3 * distances[distances.size() / 2], 1e-6 * diagonal);
  }
  r.a_from_b = t;
  r.aligned = r.refined_pairs >= 10;
  if (!r.aligned) r.why_not = "too few paired lines cross after the fit";
  return r;
}

}  // namespace linecloud
