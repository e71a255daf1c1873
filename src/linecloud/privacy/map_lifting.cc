#include "linecloud/privacy/map_lifting.h"

#include <fmt/format.h>

#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/resist.h"
#include "linecloud/util/error.h"

namespace linecloud {

std::string MapLifting::Name() const {
  std::string name;
  if (sparsify > 0) name = fmt::format("{} {:g} %", SparsifyModeName(sparsify_mode), 100 * sparsify);
  if (resist_attack >= 0) name += (name.empty() ? "" : " + ") + fmt::format("resist {:g}", resist_attack);
  if (compact) name += (name.empty() ? "" : " + ") + std::string("compact");
  return name.empty() ? "plain" : name;
}

void MapLifting::Check() const {
  if (!(sparsify >= 0 && sparsify < 1)) Fail("--sparsify: {} is not a share in [0, 1)", sparsify);
  if (resist_attack >= 1) Fail("--resist-attack: {} is not a share in [0, 1)", resist_attack);
}

LiftingKey MapLiftingKey(const LiftingKey& key, const MapLifting& lifting) {
  if (!lifting.compact || key.directions() == DirectionSet::kCompact256) return key;
  return LiftingKey(key.DeriveSubkey("linecloud/eval/compact-variant/v1"), DirectionSet::kCompact256);
}

LineCloud LiftMap(const LiftingKey& key, std::span<const uint64_t> ids,
                  std::span<const Eigen::Vector3d> points, const MapLifting& lifting) {
  lifting.Check();
  std::vector<uint64_t> kept_ids;
  std::vector<Eigen::Vector3d> kept_points;
  for (const size_t i : SelectMapPoints(key, ids, points, lifting.sparsify, lifting.sparsify_mode,
                                        lifting.resist_attack)) {
    kept_ids.push_back(ids[i]);
    kept_points.push_back(points[i]);
  }
  LiftingOptions o;
  o.encoding = lifting.compact ? LineEncoding::kCompact : LineEncoding::kPlucker;
  return LiftPoints(kept_ids, kept_points, MapLiftingKey(key, lifting), o);
}

}  // namespace linecloud
