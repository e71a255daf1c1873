// How a map is lifted for sharing, as one value: the keyed sparsification
// (lifting/sparsify.h), attack-aware sparsification (resist.h) and the
// encoding. `lift` spells these as options; `eval run` and `eval privacy`
// take the same value so that what is measured is what `lift` writes.
#pragma once

#include <functional>
#include <span>
#include <string>

#include <Eigen/Core>

#include "linecloud/io/lift_model.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/lifting/sparsify.h"

namespace linecloud {

struct MapLifting {
  double sparsify = 0;  // share dropped
  SparsifyMode sparsify_mode = SparsifyMode::kUniform;
  double resist_attack = -1;  // >= 0: lift --resist-attack after sparsifying
  // The compact encoding. Under a sphere key (the evaluation's) the lines
  // then come from a compact256 key derived from it: a second lifting of the
  // points, for measurement only, never to be shared beside the first.
  bool compact = false;

  std::string Name() const;  // e.g. "plain", "uniform 90 %", "resist 0.2", "compact"
  void Check() const;
};

// "plain", "uniform:F", "balanced:F", "resist:S", "compact", or several joined
// by '+' (e.g. "balanced:0.5+resist:0.2"); throws Error naming `source`.
MapLifting ParseMapLifting(const std::string& spec, const std::string& source);

// The key whose lines the map holds (the compact variant's derived key when
// `compact` and `key` is a sphere key).
LiftingKey MapLiftingKey(const LiftingKey& key, const MapLifting& lifting);

// `lift`'s options for this lifting (LiftModel: the keyed sparsification,
// the attack-aware selection, the encoding); `progress` gets each resist
// round's share of the kept points the attack still recovers.
void ApplyMapLifting(const MapLifting& lifting, LiftModelOptions* options,
                     std::function<void(size_t round, double recovered)> progress = nullptr);

// `lift` as the command line and Python run it: `options.model_dir` lifted
// under the model's key with this lifting (its sparsification, attack-aware
// selection and encoding replace those fields of `options`).
LiftModelResult LiftModelWith(
    LiftModelOptions options, const MapLifting& lifting,
    std::function<void(size_t round, double recovered)> progress = nullptr);

// The map of (ids, points): the kept points lifted under MapLiftingKey.
LineCloud LiftMap(const LiftingKey& key, std::span<const uint64_t> ids,
                  std::span<const Eigen::Vector3d> points, const MapLifting& lifting);

}  // namespace linecloud
