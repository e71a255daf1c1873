#include "linecloud/privacy/resist.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <unordered_map>

#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/recovery_score.h"
#include "linecloud/util/error.h"

namespace linecloud {

void ResistOptions::Check() const {
  if (!(max_recovered >= 0 && max_recovered < 1))
    Fail("--resist-attack: {} is not a share in [0, 1)", max_recovered);
  if (!(radius_percent > 0 && radius_percent <= 100)) Fail("resist: radius must be in (0, 100] %");
  if (!(drop_per_round > 0 && drop_per_round <= 1))
    Fail("resist: drop per round must be in (0, 1]");
  if (max_rounds < 1 || max_rounds > 100) Fail("resist: rounds must be in [1, 100]");
  attack.Check();
}

ResistResult SelectAttackResistantPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                         std::span<const Eigen::Vector3d> points,
                                         const ResistOptions& o) {
  o.Check();
  if (ids.size() != points.size()) Fail("resist: {} ids but {} points", ids.size(), points.size());
  ResistResult result;
  result.kept.resize(ids.size());
  for (size_t i = 0; i < ids.size(); ++i) result.kept[i] = i;
  const double radius = o.radius_percent / 100 * SceneDiagonal(points);
  for (int round = 0; round < o.max_rounds && result.kept.size() >= 10; ++round) {
    std::vector<uint64_t> kept_ids;
    std::vector<Eigen::Vector3d> kept_points;
    for (const size_t i : result.kept) kept_ids.push_back(ids[i]), kept_points.push_back(points[i]);
    const LineCloud cloud = LiftPoints(kept_ids, kept_points, key, {});
    const DensityAttackResult attack = RunDensityAttack(cloud, o.attack);
    // The cloud is in line-id order: map its lines back to the kept indices.
    const std::vector<uint64_t> line_points = PointIdsOfLines(key, cloud.ids);
    std::unordered_map<uint64_t, size_t> row_of;
    for (size_t r = 0; r < kept_ids.size(); ++r) row_of.emplace(kept_ids[r], r);
    std::vector<std::pair<float, size_t>> found;  // (peak share, index into ids)
    for (size_t k = 0; k < cloud.size(); ++k) {
      const size_t row = row_of.at(line_points[k]);
      if ((attack.points[k] - kept_points[row]).norm() <= radius) {
        found.push_back({attack.peak_share[k], result.kept[row]});
      }
    }
    const double share = static_cast<double>(found.size()) / cloud.size();
    result.recovered_share.push_back(share);
    if (share <= o.max_recovered) break;
    std::sort(found.begin(), found.end(), std::greater<>());
    const size_t excess = found.size() - static_cast<size_t>(o.max_recovered * cloud.size());
    const size_t drop = std::min(
        found.size(),
        std::max<size_t>(
            1, std::min(excess, static_cast<size_t>(std::ceil(o.drop_per_round * found.size())))));
    std::vector<bool> recovered(ids.size(), false);
    for (size_t k = 0; k < drop; ++k) recovered[found[k].second] = true;
    std::vector<size_t> next;
    for (const size_t i : result.kept) {
      if (!recovered[i]) next.push_back(i);
    }
    result.kept.swap(next);
  }
  return result;
}

std::vector<size_t> SelectMapPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                    std::span<const Eigen::Vector3d> points, double drop,
                                    SparsifyMode mode, double resist_attack) {
  std::vector<size_t> kept = SparsifyPoints(key, ids, points, drop, mode);
  if (resist_attack < 0) return kept;
  std::vector<uint64_t> kept_ids;
  std::vector<Eigen::Vector3d> kept_points;
  for (const size_t i : kept) kept_ids.push_back(ids[i]), kept_points.push_back(points[i]);
  ResistOptions o;
  o.max_recovered = resist_attack;
  std::vector<size_t> out;
  for (const size_t k : SelectAttackResistantPoints(key, kept_ids, kept_points, o).kept) {
    out.push_back(kept[k]);
  }
  return out;
}

}  // namespace linecloud
