// One physical point, one line — whatever the reconstruction calls it.
//
// Two lines with different directions through one point reveal it where they
// cross (Speciale et al., CVPR 2019, Sec. 3.1: lifting must be permanent).
// COLMAP's point ids do not name physical points: a re-triangulation, a
// mapper re-run (another gauge), an update or an export renumbers them. So a
// point's direction follows what stays across versions, recorded in the
// key's release ledger (release_ledger.h):
//   1. its observations: a point seen in an (image, keypoint) that a released
//      point was seen in keeps that point's direction, rotated into this
//      version's frame (the two reconstructions are aligned by a similarity
//      through the centres of their shared images, and checked on the matched
//      points): its line is parallel to the released one, and parallel lines
//      do not cross, wherever the point moved;
//   2. its released line, found by place: a point within `same_place` (of
//      the scene diagonal) of released lines takes the one whose descriptor
//      sketch matches its own (else the nearest) — a version whose features
//      were extracted again shares no observation. Looked up before any
//      point of this version lends its direction: a copied direction would
//      cross the point's own released line next to the point. When no
//      observation ties the versions, the alignment through the shared
//      images is verified by these lines: many more points must lie within
//      a tenth of `same_place` of a released line than would by chance;
//   3. its place in this version: a point within `same_place` of a point of
//      this version with a direction of its own takes that direction
//      (duplicates within one model);
//   4. otherwise a fresh keyed direction of its id (lifting.h) — the lines
//      of every model lifted before the ledger existed.
// A point whose observations were released with two different directions
// (a merge of two released points) cannot be given a line that crosses
// neither: it is left out of this release.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/rigid3.h"
#include "linecloud/lifting/key.h"
#include "linecloud/lifting/release_ledger.h"

namespace linecloud {

struct IdentityInput {
  std::span<const uint64_t> ids;            // point ids
  std::span<const Eigen::Vector3d> points;  // model frame
  // Point i's observation hashes (ObservationHasher) are
  // observations[observation_start[i] .. observation_start[i + 1]).
  std::span<const uint32_t> observation_start;  // ids.size() + 1 entries
  std::span<const uint64_t> observations;
  // (image hash, camera centre in the model frame) of the model's images.
  std::span<const std::pair<uint64_t, Eigen::Vector3d>> images;
  // Per point, its descriptor's sketch (DescriptorSketcher); empty: none.
  std::span<const uint64_t> sketches;
};

struct IdentityOptions {
  double same_place = 1e-3;  // share of the scene diagonal
  // Refuse when the observation-matched points lie farther than this share of
  // the diagonal (median) from their released lines after alignment.
  double max_misalignment = 1e-2;
  // A key released before ledgers existed: every released line is the keyed
  // direction of its point id, so points without a released observation keep
  // exactly that (no same-place rule) until the ledger records them.
  bool legacy_release = false;

  void Check() const;
};

struct IdentityResult {
  std::vector<Eigen::Vector3d> directions;  // per point, model frame (unit)
  // The point each line passes through, model frame: the point itself, or,
  // for a point within kMaxSnap of the released line it keeps (this version's
  // noise), the closest point of that line — the released line itself, so the
  // version adds no new line near it.
  std::vector<Eigen::Vector3d> anchors;
  size_t on_released_line = 0;       // kept lines that are the released ones themselves
  std::vector<uint8_t> compact;      // per point, compact256 keys
  std::vector<int64_t> ledger_line;  // released line kept, or -1
  std::vector<uint8_t> keep;         // 0: left out (a merge of two released lines)
  size_t from_observations = 0;
  size_t from_same_place = 0;      // a point of this version at the same place
  size_t from_released_place = 0;  // a released line within same_place
  size_t searched_by_place = 0;    // points without released observations
  // Of those, the most that found a released line with every point moved by
  // 10 x same_place along one axis: what chance gives (counted only when
  // fewer than 10 observations verify the alignment; else 0).
  size_t released_place_by_chance = 0;
  // Within a tenth of same_place: the alignment's check without observations.
  size_t released_place_close = 0, released_place_close_by_chance = 0;
  size_t released_place_by_sketch = 0;  // chosen by descriptor sketch
  double released_place_distance = 0;   // median, share of the diagonal
  size_t fresh = 0;
  size_t left_out = 0;
  Sim3d ledger_from_model;  // identity for a first release
  size_t shared_images = 0;
  double misalignment = 0;         // median, share of the diagonal
  double same_place_distance = 0;  // model units
  double diagonal = 0;             // the place's size used (model units)
};

// The farthest (share of the scene diagonal, and at most `same_place`) a
// point's line is moved onto its released line. Within `same_place` a point
// takes the released line itself rather than a parallel one: a parallel line
// through the point adds a line that crosses the released lines of the
// points around it (measured on a rebuild of fountain-P11 at same_place
// 3e-3: 27 points recovered within 1e-4 of the diagonal with parallel lines
// beyond 1e-3, 0 with the released lines).
inline constexpr double kMaxSnap = 1e-2;

// Throws Error (naming what to do) when the version cannot be aligned with the
// released one, or when a compact256 key would need a rotated direction.
IdentityResult AssignDirections(const LiftingKey& key, const IdentityInput& input,
                                const ReleaseLedger& ledger, const IdentityOptions& options);

// Adds the points `released` (indices into `input`) with their directions in
// `result` to `ledger`: new lines, their observations and the new images.
// Returns whether the ledger changed.
bool RecordRelease(const IdentityInput& input, const IdentityResult& result,
                   std::span<const size_t> released, ReleaseLedger* ledger);

}  // namespace linecloud
