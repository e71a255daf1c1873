#include "linecloud/privacy/two_key_attack.h"

#include <cmath>
#include <unordered_map>

namespace linecloud {

TwoLiftingsAttack IntersectLinesOfEqualId(const LineCloud& a, const LineCloud& b,
                                          double min_angle_rad) {
  std::unordered_map<uint64_t, size_t> index;
  index.reserve(b.size());
  for (size_t i = 0; i < b.size(); ++i) index.emplace(b.ids[i], i);
  TwoLiftingsAttack result;
  const double min_sin = std::sin(min_angle_rad);
  for (size_t i = 0; i < a.size(); ++i) {
    const auto it = index.find(a.ids[i]);
    if (it == index.end()) continue;
    ++result.shared_ids;
    const PluckerLine& la = a.lines[i];
    const PluckerLine& lb = b.lines[it->second];
    Eigen::Vector3d pa, pb;
    if (la.v.cross(lb.v).norm() < min_sin || !ClosestPoints(la, lb, &pa, &pb)) {
      ++result.parallel;
      continue;
    }
    result.ids.push_back(a.ids[i]);
    result.points.push_back(0.5 * (pa + pb));
  }
  return result;
}

}  // namespace linecloud
