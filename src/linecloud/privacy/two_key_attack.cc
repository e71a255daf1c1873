#include "linecloud/privacy/two_key_attack.h"

#include <cmath>
#include <limits>
#include <unordered_map>

#include "linecloud/features/matching.h"
#include "linecloud/geometry/line_grid.h"
#include "linecloud/privacy/line_neighbours.h"
#include "linecloud/util/error.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/util/parallel.h"

namespace linecloud {
namespace {

// The crossing attacks' grids: 4 bytes per entry, 512 MB at most.
constexpr size_t kCrossingGridEntries = size_t{1} << 27;

// Squared distance between two lines in double precision (∞ when parallel).
double LineDistanceSq(const Eigen::Vector3d& v1, const Eigen::Vector3d& q1,
                      const Eigen::Vector3d& v2, const Eigen::Vector3d& q2) {
  const Eigen::Vector3d n = v1.cross(v2);
  const double s2 = n.squaredNorm();
  if (s2 < 1e-16) return std::numeric_limits<double>::infinity();
  const double d = (q2 - q1).dot(n);
  return d * d / s2;
}

// Intersects line i of `a` with its partner: the recovered point, or a
// parallel pair (no crossing).
void Intersect(const LineCloud& a, size_t i, const PluckerLine& partner, double min_sin,
               TwoLiftingsAttack* result) {
  ++result->shared_ids;
  const PluckerLine& la = a.lines[i];
  Eigen::Vector3d pa, pb;
  if (la.v.cross(partner.v).norm() < min_sin || !ClosestPoints(la, partner, &pa, &pb)) {
    ++result->parallel;
    return;
  }
  result->ids.push_back(a.ids[i]);
  result->indices.push_back(i);
  result->points.push_back(0.5 * (pa + pb));
}

}  // namespace

TwoLiftingsAttack IntersectLinesOfEqualId(const LineCloud& a, const LineCloud& b,
                                          double min_angle_rad) {
  std::unordered_map<uint64_t, size_t> index;
  index.reserve(b.size());
  for (size_t i = 0; i < b.size(); ++i) index.emplace(b.ids[i], i);
  TwoLiftingsAttack result;
  result.pairing = "equal ids";
  const double min_sin = std::sin(min_angle_rad);
  for (size_t i = 0; i < a.size(); ++i) {
    const auto it = index.find(a.ids[i]);
    if (it != index.end()) Intersect(a, i, b.lines[it->second], min_sin, &result);
  }
  return result;
}

TwoLiftingsAttack IntersectCrossingLines(const LineCloud& a, const LineCloud& b,
                                         double max_relative_distance, int threads) {
  TwoLiftingsAttack result;
  result.pairing = "crossing";
  if (a.size() == 0 || b.size() == 0) return result;
  std::vector<Eigen::Vector3d> anchors;
  for (const PluckerLine& l : a.lines) anchors.push_back(l.Anchor());
  const double diagonal = SceneDiagonal(anchors);
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const auto& p : anchors) centre += p;
  centre /= static_cast<double>(anchors.size());
  const LineArrays la = MakeLineArrays(a.lines, centre);
  const LineArrays lb = MakeLineArrays(b.lines, centre);
  const double max_sq = std::pow(max_relative_distance * diagonal, 2);
  // float32 candidates, then the nearest among them in double precision.
  constexpr size_t kCandidates = 8;
  const int workers = WorkerThreads(threads);
  struct Scratch {
    std::vector<float> d2;
    SelectBuffers select;
    std::vector<uint32_t> nearest;
  };
  std::vector<Scratch> scratch(workers);
  for (Scratch& s : scratch) s.d2.resize(b.size());
  std::vector<int64_t> partner(a.size(), -1);
  ParallelFor(a.size(), workers, [&](size_t i, int w) {
    Scratch& s = scratch[w];
    // Only exactly parallel pairs are excluded: lines of one point may be
    // nearly parallel and still cross.
    LineToLinesSq(la, i, lb, s.d2.data(), 1e-12f);
    SmallestK(s.d2, kCandidates, &s.select, &s.nearest);
    double best = std::numeric_limits<double>::infinity();
    for (const uint32_t j : s.nearest) {
      const double d = LineDistanceSq(la.v[i], la.q[i], lb.v[j], lb.q[j]);
      if (d < best) best = d, partner[i] = j;
    }
    if (!(best <= max_sq)) partner[i] = -1;
  });
  for (size_t i = 0; i < a.size(); ++i) {
    if (partner[i] >= 0) Intersect(a, i, b.lines[partner[i]], 0.0, &result);
  }
  return result;
}

TwoLiftingsAttack IntersectLinesOfNearestDescriptor(const LineCloud& a, const LineCloud& b,
                                                    double min_angle_rad) {
  TwoLiftingsAttack result;
  result.pairing = "nearest descriptor";
  if (!a.has_descriptors() || !b.has_descriptors() || a.descriptor_dim != b.descriptor_dim) {
    Fail("pairing by descriptor: both maps need descriptors of one size ({} and {})",
         a.descriptor_dim, b.descriptor_dim);
  }
  DescriptorMatchOptions o;
  o.dim = a.descriptor_dim;
  o.max_ratio = 1.0;     // no ratio test: the nearest, whatever the second
  o.max_distance = 3.2;  // no distance test (angles are at most π)
  // A tie (ratio exactly 1) is refused by the ratio test; the attacker keeps
  // the nearest anyway: ties are rare among real descriptors.
  const std::vector<DescriptorMatch> matches = MatchDescriptors(a.descriptors, b.descriptors, o);
  const double min_sin = std::sin(min_angle_rad);
  for (const DescriptorMatch& m : matches) Intersect(a, m.query, b.lines[m.map], min_sin, &result);
  return result;
}

TwoLiftingsAttack IntersectCrossingLinesInBox(const LineCloud& a, const LineCloud& b,
                                              const Eigen::AlignedBox3d& box, double tolerance,
                                              double min_angle_rad, int threads) {
  TwoLiftingsAttack result;
  result.pairing = "crossing lines";
  std::vector<PluckerLine> lines(a.lines.begin(), a.lines.end());
  lines.insert(lines.end(), b.lines.begin(), b.lines.end());
  std::vector<uint8_t> group(a.size(), 0);
  group.resize(lines.size(), 1);
  const LineGrid grid(lines, box, tolerance, kCrossingGridEntries);
  grid.CrossingPairs(
      min_angle_rad, group,
      [&](uint32_t i, uint32_t j, const Eigen::Vector3d& mid, double) {
        ++result.shared_ids;
        result.ids.push_back(a.ids[i]);
        result.indices.push_back(i);
        result.points.push_back(mid);
        (void)j;
      },
      threads);
  return result;
}

size_t ForEachSelfCrossing(
    const LineCloud& a, const Eigen::AlignedBox3d& box, double tolerance,
    const std::function<void(uint32_t, uint32_t, const Eigen::Vector3d&)>& found,
    double min_angle_rad, int threads) {
  size_t pairs = 0;
  const LineGrid grid(a.lines, box, tolerance, kCrossingGridEntries);
  grid.CrossingPairs(
      min_angle_rad, {},
      [&](uint32_t i, uint32_t j, const Eigen::Vector3d& mid, double) {
        ++pairs;
        found(i, j, mid);
      },
      threads);
  return pairs;
}

TwoLiftingsAttack AttackTwoLiftings(const LineCloud& a, const LineCloud& b, int threads) {
  std::unordered_map<uint64_t, size_t> index;
  for (size_t i = 0; i < b.size(); ++i) index.emplace(b.ids[i], i);
  size_t shared = 0;
  for (const uint64_t id : a.ids) shared += index.count(id);
  if (2 * shared >= a.size() && shared > 0) return IntersectLinesOfEqualId(a, b);
  // Lines of one point cross to rounding: ~1e-15 of the scene in float64,
  // ~1e-7 in the compact encoding's float32 (where chance near-crossings of
  // different points' lines start to compete).
  const bool exact = a.encoding == LineEncoding::kPlucker && b.encoding == LineEncoding::kPlucker;
  return IntersectCrossingLines(a, b, exact ? 1e-9 : 1e-6, threads);
}

}  // namespace linecloud
