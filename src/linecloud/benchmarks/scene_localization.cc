#include "linecloud/benchmarks/scene_localization.h"

#include <algorithm>
#include <random>

#include "linecloud/synthetic/localization_instances.h"
#include "linecloud/util/error.h"

namespace linecloud {
MethodSummary EvaluateMethod(const MethodInfo& method, const std::vector<SceneQuery>& queries,
                             const LocalizationMap& map, const LocalizeOptions& options,
                             double max_rotation_deg, double max_position) {
  LocalizationTally tally(max_rotation_deg, max_position);
  for (const SceneQuery& sq : queries) {
    // A query the method cannot use (e.g. fewer observations than its sample
    // in a tiny demo scene) has no pose, with the reason, like any failure.
    LocalizeResult r;
    try {
      r = Localize(method, sq.query, map, options, sq.name);
    } catch (const Error& e) {
      r.failure = e.what();
      const std::string prefix = sq.name + ": ";
      if (r.failure.rfind(prefix, 0) == 0) r.failure.erase(0, prefix.size());
    }
    tally.Add(r, sq.truth, 1.0, sq.name);
  }
  MethodSummary summary;
  static_cast<LocalizationSummary&>(summary) = tally.Summary();
  summary.method = std::string(method.name);
  return summary;
}

}  // namespace linecloud
