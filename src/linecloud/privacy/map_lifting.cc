#include "linecloud/privacy/map_lifting.h"

#include <cmath>
#include <cstdlib>

#include <fmt/format.h>

#include "linecloud/lifting/lifting.h"
#include "linecloud/privacy/resist.h"
#include "linecloud/util/error.h"

namespace linecloud {

std::string MapLifting::Name() const {
  std::string name;
  if (sparsify > 0)
    name = fmt::format("{} {:g} %", SparsifyModeName(sparsify_mode), 100 * sparsify);
  if (resist_attack >= 0)
    name += (name.empty() ? "" : " + ") + fmt::format("resist {:g}", resist_attack);
  if (compact) name += (name.empty() ? "" : " + ") + std::string("compact");
  return name.empty() ? "plain" : name;
}

void MapLifting::Check() const {
  if (!(sparsify >= 0 && sparsify < 1)) Fail("--sparsify: {} is not a share in [0, 1)", sparsify);
  if (resist_attack >= 1) Fail("--resist-attack: {} is not a share in [0, 1)", resist_attack);
}

MapLifting ParseMapLifting(const std::string& spec, const std::string& source) {
  MapLifting m;
  size_t start = 0;
  while (start <= spec.size()) {
    const size_t end = std::min(spec.find('+', start), spec.size());
    const std::string part = spec.substr(start, end - start);
    const size_t colon = part.find(':');
    const std::string name = part.substr(0, colon);
    double value = 0;
    if (colon != std::string::npos) {
      const std::string number = part.substr(colon + 1);
      char* rest = nullptr;
      value = std::strtod(number.c_str(), &rest);
      if (number.empty() || *rest != '\0' || !std::isfinite(value)) {
        Fail("{}: '{}' is not a number in '{}'", source, number, spec);
      }
    }
    const bool needs_value = name == "uniform" || name == "balanced" || name == "resist";
    if (needs_value != (colon != std::string::npos)) {
      Fail("{}: '{}' in '{}' (expected plain, uniform:F, balanced:F, resist:S or compact)", source,
           part, spec);
    }
    if (name == "uniform" || name == "balanced") {
      m.sparsify = value;
      m.sparsify_mode = name == "balanced" ? SparsifyMode::kBalanced : SparsifyMode::kUniform;
    } else if (name == "resist") {
      m.resist_attack = value;
      if (value < 0) Fail("{}: resist share {} < 0", source, value);
    } else if (name == "compact") {
      m.compact = true;
    } else if (name != "plain") {
      Fail("{}: unknown lifting '{}' in '{}' (plain, uniform:F, balanced:F, resist:S, compact)",
           source, name, spec);
    }
    start = end + 1;
  }
  m.Check();
  return m;
}

LiftingKey MapLiftingKey(const LiftingKey& key, const MapLifting& lifting) {
  if (!lifting.compact || key.directions() == DirectionSet::kCompact256) return key;
  return LiftingKey(key.DeriveSubkey("linecloud/eval/compact-variant/v1"),
                    DirectionSet::kCompact256);
}

void ApplyMapLifting(const MapLifting& lifting, LiftModelOptions* options,
                     std::function<void(size_t, double)> progress) {
  lifting.Check();
  options->sparsify = lifting.sparsify;
  options->sparsify_mode = lifting.sparsify_mode;
  options->compact = lifting.compact;
  options->select_points = nullptr;
  if (lifting.resist_attack < 0) return;
  ResistOptions resist;
  resist.max_recovered = lifting.resist_attack;
  resist.Check();
  options->select_points = [resist, progress](const LiftingKey& key, std::span<const uint64_t> ids,
                                              std::span<const Eigen::Vector3d> points) {
    const ResistResult r = SelectAttackResistantPoints(key, ids, points, resist);
    if (progress) {
      for (size_t k = 0; k < r.recovered_share.size(); ++k) progress(k + 1, r.recovered_share[k]);
    }
    return r.kept;
  };
}

LiftModelResult LiftModelWith(LiftModelOptions options, const MapLifting& lifting,
                              std::function<void(size_t, double)> progress) {
  ApplyMapLifting(lifting, &options, std::move(progress));
  return LiftModel(options);
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
