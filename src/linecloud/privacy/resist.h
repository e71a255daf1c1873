// A lifting of our own that resists the density attack: attack-aware
// sparsification. The owner knows the secret points, so before sharing a map
// the owner can run the attack on it (density_attack.h) and see which points
// come back. The recovered points whose votes agree the most are dropped —
// just enough of them to reach the target if nothing else changed — and the
// attack is run again on what is left (their removal changes everybody's
// neighbourhoods), until at most `max_recovered` of the kept points are
// recovered within `radius_percent` % of the scene's diagonal, or
// `max_rounds` rounds.
//
// Every kept point keeps its line (same key, same line as the full map), so
// this is a subset of the full map's lines like `--sparsify`; it is
// deterministic in (key, model): the attack is. It targets the attack's
// mechanism — points with dense, consistent neighbourhoods — instead of
// thinning blindly. Limits: it is tuned against this attack with these
// parameters; the audit of the result with other attack parameters tells how
// much that matters (see docs/privacy.md).
#pragma once

#include <span>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/key.h"
#include "linecloud/lifting/sparsify.h"
#include "linecloud/privacy/density_attack.h"

namespace linecloud {

struct ResistOptions {
  double max_recovered = 0.2;   // share of the kept points recovered at the end
  double radius_percent = 1.0;  // "recovered": within this % of the diagonal
  int max_rounds = 10;
  // Per round, only this share of the recovered points goes: those whose
  // votes agree the most (largest peak share) — removing a point also
  // changes its neighbours' votes, so fewer go overall.
  double drop_per_round = 1.0;
  DensityAttackOptions attack;

  void Check() const;
};

struct ResistResult {
  std::vector<size_t> kept;             // indices into ids/points, increasing
  std::vector<double> recovered_share;  // after each round, of the points kept then
};

ResistResult SelectAttackResistantPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                         std::span<const Eigen::Vector3d> points,
                                         const ResistOptions& options);

// The points a map keeps: `lift --sparsify drop --sparsify-mode mode` and,
// when resist_attack >= 0, `--resist-attack resist_attack` after it. Returns
// indices into (ids, points), increasing.
std::vector<size_t> SelectMapPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                    std::span<const Eigen::Vector3d> points, double drop,
                                    SparsifyMode mode, double resist_attack);

}  // namespace linecloud
