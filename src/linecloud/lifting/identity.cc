#include "linecloud/lifting/identity.h"

#include <algorithm>
#include <array>
#include <limits>
#include <bit>
#include <cmath>

#include <Eigen/Geometry>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/geometry/similarity_fit.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

Eigen::Vector3d Apply(const Sim3d& t, const Eigen::Vector3d& x) { return t * x; }

// Similarity ledger_from_model through the shared images' centres
// (similarity_fit.h: triples, fixed seed, refitted on the inliers, within 2 %
// of the centres' spread).
Sim3d AlignThroughImages(const std::vector<Eigen::Vector3d>& model,
                         const std::vector<Eigen::Vector3d>& ledger) {
  const size_t n = model.size();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& c : ledger) mean += c;
  mean /= static_cast<double>(n);
  double spread = 0;
  for (const auto& c : ledger) spread += (c - mean).squaredNorm();
  spread = std::sqrt(spread / static_cast<double>(n));
  // The same gauge (a re-triangulation, an update): exactly the identity, so
  // that a re-lift gives bit-identical lines.
  double worst = 0;
  for (size_t k = 0; k < n; ++k) worst = std::max(worst, (model[k] - ledger[k]).norm());
  if (worst <= 1e-9 * std::max(spread, 1e-300)) return Sim3d();
  const RobustSimilarityFit fit = FitSimilarityRobust(model, ledger, 0.02 * spread);
  return fit.dst_from_src.scale > 0 ? fit.dst_from_src : Sim3d();
}

// Sketches of one physical point's descriptors differ in at most about this
// many bits of 64 (≈ 0.8 rad; SIFT matches lie below 0.7 rad, unrelated
// descriptors near 1.2).
constexpr int kMaxSketchBits = 16;
// How far (in same_place) a released line whose sketch matches is looked
// for: a rebuilt point lying 1-3 same_place from its released point would
// otherwise get a line crossing it there (measured on the Strecha scenes at
// same_place 1e-3: ~1 % of the points recovered within 1e-3 of the diagonal
// by descriptor pairing, 0.4 % with the reach).
constexpr double kSketchReach = 3;

bool SameDirection(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return a.cross(b).norm() <= 1e-9;
}

}  // namespace

void IdentityOptions::Check() const {
  if (!(same_place > 0 && same_place < 0.1)) {
    Fail("identity: same_place {} is not a share of the diagonal in (0, 0.1)", same_place);
  }
  if (!(max_misalignment > 0 && max_misalignment < 1)) {
    Fail("identity: max_misalignment {} is not a share in (0, 1)", max_misalignment);
  }
}

namespace {

// One assignment's state, shared by its stages.
struct Assignment {
  Assignment(const LiftingKey& k, const IdentityInput& input, const ReleaseLedger& l,
             const IdentityOptions& options)
      : key(k), in(input), ledger(l), o(options) {}
  const LiftingKey& key;
  const IdentityInput& in;
  const ReleaseLedger& ledger;
  const IdentityOptions& o;
  IdentityResult r;
  bool compact_key = false, rotated = false;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Sim3d model_from_ledger;
  double diagonal = 0, snap = 0;
  // 0: no direction yet; 1: a direction of its own; 2: copied (same place).
  std::vector<uint8_t> assigned;
  std::vector<double> observed_distances;  // share of the diagonal

  size_t size() const { return in.ids.size(); }
  Eigen::Vector3d InLedger(size_t i) const { return Apply(r.ledger_from_model, in.points[i]); }

  // Point i keeps released line `l`: its direction, moved into this frame;
  // the line itself when it passes within `snap` of the point (not exactly
  // through it: then the point stays).
  void Take(size_t i, int64_t l) {
    const PluckerLine& line = ledger.lines[l];
    r.ledger_line[i] = l;
    r.directions[i] = rotation.transpose() * line.v;
    r.compact[i] = ledger.compact[l];
    assigned[i] = 1;
    const Eigen::Vector3d p = Apply(model_from_ledger, line.ClosestPointTo(InLedger(i)));
    const double d = (p - in.points[i]).norm();
    if (d <= snap) {
      if (d > 1e-12 * std::max(diagonal, 1e-300)) r.anchors[i] = p;
      ++r.on_released_line;
    }
  }
};

void CheckInput(const IdentityInput& in) {
  const size_t n = in.ids.size();
  if (in.points.size() != n || in.observation_start.size() != n + 1 ||
      in.observation_start[n] != in.observations.size()) {
    Fail("identity: {} ids, {} points, {} observation starts for {} observations", n,
         in.points.size(), in.observation_start.size(), in.observations.size());
  }
  for (size_t i = 0; i < n; ++i) {
    if (!in.points[i].allFinite()) Fail("identity: point {} has non-finite coordinates", in.ids[i]);
  }
  for (const auto& [hash, centre] : in.images) {
    if (!centre.allFinite()) Fail("identity: an image centre has non-finite coordinates");
  }
  if (!in.sketches.empty() && in.sketches.size() != n) {
    Fail("identity: {} descriptor sketches for {} points", in.sketches.size(), n);
  }
}

// The similarity ledger_from_model through the images both versions share.
void AlignWithLedger(Assignment* a) {
  IdentityResult& r = a->r;
  if (!a->ledger.empty()) {
    std::vector<Eigen::Vector3d> model_c, ledger_c;
    for (const auto& [hash, centre] : a->in.images) {
      // An image may be listed under two hashes (its name, its features):
      // once per image.
      if (!model_c.empty() && model_c.back() == centre) continue;
      if (const Eigen::Vector3d* c = a->ledger.ImageCentre(hash)) {
        model_c.push_back(centre);
        ledger_c.push_back(*c);
      }
    }
    r.shared_images = model_c.size();
    if (model_c.size() >= 3) r.ledger_from_model = AlignThroughImages(model_c, ledger_c);
  }
  a->rotation = r.ledger_from_model.rotation.toRotationMatrix();
  a->model_from_ledger = r.ledger_from_model.Inverse();
  a->rotated = (a->rotation - Eigen::Matrix3d::Identity()).norm() > 1e-9;
}

// 1. A point seen in released observations keeps their line.
void KeepObservedLines(Assignment* a) {
  IdentityResult& r = a->r;
  const ReleaseLedger& ledger = a->ledger;
  std::vector<std::pair<int64_t, int>> votes;
  for (size_t i = 0; i < a->size() && !ledger.empty(); ++i) {
    votes.clear();
    for (uint32_t k = a->in.observation_start[i]; k < a->in.observation_start[i + 1]; ++k) {
      const int64_t line = ledger.LineOfObservation(a->in.observations[k]);
      if (line < 0) continue;
      auto it =
          std::find_if(votes.begin(), votes.end(), [&](const auto& v) { return v.first == line; });
      if (it == votes.end())
        votes.push_back({line, 1});
      else
        ++it->second;
    }
    if (votes.empty()) continue;
    const auto best =
        *std::max_element(votes.begin(), votes.end(), [](const auto& x, const auto& y) {
          return x.second < y.second || (x.second == y.second && x.first > y.first);
        });
    const PluckerLine& line = ledger.lines[best.first];
    bool conflict = false;
    for (const auto& v : votes) conflict |= !SameDirection(ledger.lines[v.first].v, line.v);
    if (conflict) {
      r.keep[i] = 0;
      ++r.left_out;
      continue;
    }
    a->Take(i, best.first);
    ++r.from_observations;
    a->observed_distances.push_back(line.DistanceTo(a->InLedger(i)) /
                                    (r.ledger_from_model.scale * std::max(a->diagonal, 1e-300)));
  }
}

// 2. A point within `same_place` of a released line takes the nearest one —
// before any point of this version lends it a direction: a copied direction
// would cross the point's own released line next to the point. Versions
// whose features were extracted again share no observation; this finds
// their released lines. Also counts how many points would find a line by
// chance (the points moved by 10 x same_place along each axis, the most of
// the six), which verifies the alignment.
void FindReleasedLines(Assignment* a) {
  IdentityResult& r = a->r;
  if (a->ledger.empty() || (a->compact_key && a->rotated)) return;
  const size_t n = a->size();
  std::vector<Eigen::Vector3d> in_ledger(n);
  for (size_t k = 0; k < n; ++k) in_ledger[k] = a->InLedger(k);
  const double radius = r.same_place_distance * r.ledger_from_model.scale;
  const double reach = kSketchReach * radius;
  const LineGrid grid(a->ledger.lines, RobustBox(in_ledger, 0.005, 0.05), reach);
  std::vector<uint32_t> near;
  std::vector<double> distances;
  std::array<size_t, 6> chance{}, close_chance{};
  // Whether a line within `within` of x is among `near`.
  const auto any_within = [&](const Eigen::Vector3d& x, double within) {
    for (const uint32_t l : near) {
      if (a->ledger.lines[l].DistanceTo(x) <= within) return true;
    }
    return false;
  };
  // Chance is only asked about when observations do not verify the alignment.
  const bool count_chance = r.from_observations < 10;
  for (size_t i = 0; i < n; ++i) {
    if (a->assigned[i] || !r.keep[i]) continue;
    ++r.searched_by_place;
    for (int s = 0; s < 6 && count_chance; ++s) {
      Eigen::Vector3d x = in_ledger[i];
      x[s / 2] += (s % 2 ? -10 : 10) * radius;
      grid.LinesNear(x, &near);
      chance[s] += any_within(x, radius);
      close_chance[s] += any_within(x, 0.1 * radius);
    }
    grid.LinesNear(in_ledger[i], &near);
    // Other points' lines pass this close too (about one per point within
    // 1e-3 of the diagonal in a dense scene): the line whose point's
    // descriptor sketch matches this one's, up to kSketchReach x same_place;
    // else the nearest within same_place.
    const uint64_t sketch = a->in.sketches.empty() ? 0 : a->in.sketches[i];
    double best_d = std::numeric_limits<double>::infinity();
    int64_t best_line = -1, by_sketch = -1;
    int best_bits = kMaxSketchBits + 1;
    double by_sketch_d = 0;
    for (const uint32_t l : near) {
      const double d = a->ledger.lines[l].DistanceTo(in_ledger[i]);
      if (d <= radius && d < best_d) best_d = d, best_line = l;
      const int bits = SketchDistance(sketch, a->ledger.sketch[l]);
      if (bits < best_bits || (bits == best_bits && d < by_sketch_d)) {
        best_bits = bits, by_sketch = l, by_sketch_d = d;
      }
    }
    if (best_line >= 0 && best_d <= 0.1 * radius) ++r.released_place_close;
    if (by_sketch >= 0) {
      best_line = by_sketch;
      best_d = by_sketch_d;
      ++r.released_place_by_sketch;
    }
    if (best_line < 0) continue;
    a->Take(i, best_line);
    ++r.from_released_place;
    distances.push_back(best_d / (r.ledger_from_model.scale * std::max(a->diagonal, 1e-300)));
  }
  r.released_place_by_chance = *std::max_element(chance.begin(), chance.end());
  r.released_place_close_by_chance = *std::max_element(close_chance.begin(), close_chance.end());
  if (!distances.empty()) {
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    r.released_place_distance = distances[distances.size() / 2];
  }
}

// Refuses a version whose alignment with the released one nothing verifies.
void CheckAlignment(Assignment* a) {
  IdentityResult& r = a->r;
  if (a->ledger.empty()) return;
  if (a->compact_key && a->rotated) {
    Fail(
        "this version of the model has another gauge than its released version, and a "
        "compact256 key's 256 directions cannot follow the rotation between them: align it "
        "to the released model first (colmap model_aligner), or lift with a sphere key");
  }
  std::vector<double>& distances = a->observed_distances;
  if (distances.size() >= 10) {
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    r.misalignment = distances[distances.size() / 2];
    if (!(r.misalignment <= a->o.max_misalignment)) {
      Fail(
          "this version of the model shares {} observations with its released version but "
          "cannot be aligned with it ({} shared images; after alignment its points lie {:.2g} % "
          "of the scene diagonal from their released lines, median): lifting it would give "
          "those points crossing lines. Align it to the released version first (colmap "
          "model_aligner) and lift it from the released version's database; a key of its own "
          "(--key-file NEW --force) only if it is another place, never for the same scene",
          r.from_observations, r.shared_images, 100 * r.misalignment);
    }
  } else {
    // No observations to check the frames against (features extracted
    // again): the points lying on released lines (within a tenth of
    // same_place; about one line per point passes within same_place of any
    // place in a dense scene) must be many more than chance would give.
    const bool verified = r.shared_images >= 3 && r.released_place_close >= 10 &&
                          r.released_place_close >= 3 * r.released_place_close_by_chance;
    if (!verified) {
      Fail(
          "this version of the model cannot be aligned with its released version, and its "
          "lines could cross the released ones: it shares {} images and {} observations with "
          "it, and after alignment {} of its {} points lie within a tenth of --same-place of a "
          "released line where {} would by chance. Lift it from the released version's database "
          "(its "
          "features) with the released images, or rebuild it with the same photos (their "
          "names or features tie the versions together); a key of its own (--key-file NEW "
          "--force) only if it is another place, never for the same scene",
          r.shared_images, r.from_observations, r.released_place_close, r.searched_by_place,
          r.released_place_close_by_chance);
    }
    r.misalignment = r.released_place_distance;
  }
}

// 3. A point within `same_place` of a point of this version with a direction
// of its own takes that direction (no chains: a bundle of parallel lines
// stays within `same_place` of its seed); 4. otherwise a fresh keyed one.
// Points are sorted into cells of side 2 eps: the eps-ball of a point then
// meets at most the 8 cells on its side of each half cell.
void CopySamePlaceOrFresh(Assignment* a) {
  IdentityResult& r = a->r;
  const size_t n = a->size();
  const std::span<const Eigen::Vector3d> points = a->in.points;
  std::vector<Eigen::Vector3d> fresh(n);
  std::vector<uint8_t> fresh_compact(n);
  KeyedDirections(a->key, a->in.ids, fresh.data(), fresh_compact.data());
  if (a->compact_key) {
    for (size_t i = 0; i < n; ++i) fresh[i] = CompactDirections()[fresh_compact[i]];
  }
  const double eps = r.same_place_distance;
  const double side = 2 * eps;
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& x : points) low = low.cwiseMin(x);
  constexpr int64_t kAxisCells = int64_t{1} << 21;
  const auto cell_coord = [&](double v, int axis) {
    const double c = std::floor((v - low[axis]) / side);
    return static_cast<int64_t>(std::clamp(c, 0.0, static_cast<double>(kAxisCells - 1)));
  };
  const auto pack = [](int64_t x, int64_t y, int64_t z) {
    return static_cast<uint64_t>((z << 42) | (y << 21) | x);
  };
  std::vector<std::pair<uint64_t, uint32_t>> cells(n);
  for (size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& x = points[i];
    cells[i] = {pack(cell_coord(x.x(), 0), cell_coord(x.y(), 1), cell_coord(x.z(), 2)),
                static_cast<uint32_t>(i)};
  }
  std::sort(cells.begin(), cells.end());
  // Each occupied cell's first entry, by an open-addressing table on its key.
  const size_t slots = std::bit_ceil(std::max<size_t>(2 * n, 16));
  std::vector<uint64_t> slot_key(slots, ~uint64_t{0});
  std::vector<uint32_t> slot_start(slots, 0);
  const auto slot_of = [&](uint64_t key) {
    size_t h = static_cast<size_t>((key * 0x9E3779B97F4A7C15ull) >> 20) & (slots - 1);
    while (slot_key[h] != ~uint64_t{0} && slot_key[h] != key) h = (h + 1) & (slots - 1);
    return h;
  };
  for (size_t k = 0; k < n; ++k) {
    if (k > 0 && cells[k].first == cells[k - 1].first) continue;
    const size_t h = slot_of(cells[k].first);
    slot_key[h] = cells[k].first;
    slot_start[h] = static_cast<uint32_t>(k);
  }
  std::vector<uint8_t>& assigned = a->assigned;
  // In cell order (neighbours are near in memory); a deterministic order.
  for (const auto& [cell_key, point] : cells) {
    const size_t i = point;
    if (assigned[i] || !r.keep[i]) continue;
    if (a->o.legacy_release) {
      r.directions[i] = fresh[i];
      r.compact[i] = fresh_compact[i];
      assigned[i] = 1;
      ++r.fresh;
      continue;
    }
    const Eigen::Vector3d& x = points[i];
    int64_t c[3], step[3];
    for (int k = 0; k < 3; ++k) {
      c[k] = cell_coord(x[k], k);
      const double frac = (x[k] - low[k]) / side - static_cast<double>(c[k]);
      step[k] = frac < 0.5 ? -1 : 1;
    }
    double best_d = std::numeric_limits<double>::infinity();
    int64_t best_j = -1;
    for (int corner = 0; corner < 8; ++corner) {
      const int64_t cx = c[0] + ((corner & 1) ? step[0] : 0);
      const int64_t cy = c[1] + ((corner & 2) ? step[1] : 0);
      const int64_t cz = c[2] + ((corner & 4) ? step[2] : 0);
      if (cx < 0 || cy < 0 || cz < 0 || cx >= kAxisCells || cy >= kAxisCells || cz >= kAxisCells) {
        continue;
      }
      const uint64_t key = pack(cx, cy, cz);
      const size_t h = slot_of(key);
      if (slot_key[h] != key) continue;
      for (size_t e = slot_start[h]; e < n && cells[e].first == key; ++e) {
        const uint32_t j = cells[e].second;
        if (j == i || assigned[j] != 1 || !r.keep[j]) continue;
        const double d = (points[j] - x).norm();
        if (d <= eps && d < best_d) best_d = d, best_j = j;
      }
    }
    if (best_j >= 0) {
      r.directions[i] = r.directions[best_j];
      r.compact[i] = r.compact[best_j];
      r.ledger_line[i] = r.ledger_line[best_j];
      assigned[i] = 2;
      ++r.from_same_place;
      continue;
    }
    r.directions[i] = fresh[i];
    r.compact[i] = fresh_compact[i];
    assigned[i] = 1;
    ++r.fresh;
  }
}

}  // namespace

IdentityResult AssignDirections(const LiftingKey& key, const IdentityInput& in,
                                const ReleaseLedger& ledger, const IdentityOptions& o) {
  o.Check();
  CheckInput(in);
  const size_t n = in.ids.size();
  Assignment a(key, in, ledger, o);
  IdentityResult& r = a.r;
  a.compact_key = key.directions() == DirectionSet::kCompact256;
  r.directions.resize(n);
  r.compact.assign(n, 0);
  r.ledger_line.assign(n, -1);
  r.keep.assign(n, 1);
  r.anchors.assign(in.points.begin(), in.points.end());
  a.assigned.assign(n, 0);
  AlignWithLedger(&a);
  // The place's size: this version's, or the released scene's when that is
  // larger (a piece of the scene lifted on its own keeps the scene's
  // same_place, or its points would miss their released lines).
  a.diagonal = RobustBox(in.points, 0.005, 0.0).diagonal().norm();
  if (ledger.diagonal > 0) {
    a.diagonal = std::max(a.diagonal, ledger.diagonal / r.ledger_from_model.scale);
  }
  r.diagonal = a.diagonal;
  r.same_place_distance = std::max(o.same_place * a.diagonal, 1e-12);
  a.snap = std::min(kSketchReach * o.same_place, kMaxSnap) * a.diagonal;
  KeepObservedLines(&a);
  if (!ledger.empty() && r.shared_images < 3 && r.from_observations < 10) {
    // Nothing ties this version to the released one: neither a similarity
    // (3 shared images) nor observations to check the frames against. Fresh
    // lines could cross the released ones wherever the frames differ.
    Fail(
        "this version of the model shares {} images and {} observations with its released "
        "version: they cannot be aligned, and its lines could cross the released ones. Lift it "
        "from the released version's database (its features), with the released images; a key "
        "of its own (--key-file NEW --force) only if it is another place, never for the same "
        "scene",
        r.shared_images, r.from_observations);
  }
  FindReleasedLines(&a);
  CheckAlignment(&a);
  CopySamePlaceOrFresh(&a);
  return std::move(a.r);
}

bool RecordRelease(const IdentityInput& in, const IdentityResult& r,
                   std::span<const size_t> released, ReleaseLedger* ledger) {
  const size_t lines_before = ledger->lines.size();
  bool sketched = false;
  const double diagonal_before = ledger->diagonal;
  if (!released.empty()) {
    ledger->diagonal = std::max(ledger->diagonal, r.diagonal * r.ledger_from_model.scale);
  }
  const Sim3d& t = r.ledger_from_model;
  const Eigen::Matrix3d rotation = t.rotation.toRotationMatrix();
  std::vector<std::pair<uint64_t, uint32_t>> added;
  for (const size_t i : released) {
    if (i >= r.keep.size() || !r.keep[i]) Fail("identity: point {} was not given a line", i);
    int64_t line = r.ledger_line[i];
    if (line < 0) {
      // Not renormalised: the same gauge gives back exactly this direction.
      const Eigen::Vector3d v = rotation * r.directions[i];
      ledger->lines.push_back(PluckerLine(v, Apply(t, in.points[i]).cross(v)));
      ledger->compact.push_back(r.compact[i]);
      ledger->sketch.push_back(in.sketches.empty() ? 0 : in.sketches[i]);
      line = static_cast<int64_t>(ledger->lines.size()) - 1;
    } else if (ledger->sketch[line] == 0 && !in.sketches.empty() && in.sketches[i] != 0) {
      ledger->sketch[line] = in.sketches[i];  // a line released before sketches
      sketched = true;
    }
    for (uint32_t k = in.observation_start[i]; k < in.observation_start[i + 1]; ++k) {
      if (ledger->LineOfObservation(in.observations[k]) < 0) {
        added.push_back({in.observations[k], static_cast<uint32_t>(line)});
      }
    }
  }
  if (!added.empty()) {
    // Sorted, then merged after the sorted released ones (a first one kept).
    const auto by_hash = [](const auto& a, const auto& b) { return a.first < b.first; };
    std::stable_sort(added.begin(), added.end(), by_hash);
    const size_t middle = ledger->observations.size();
    ledger->observations.insert(ledger->observations.end(), added.begin(), added.end());
    std::inplace_merge(ledger->observations.begin(), ledger->observations.begin() + middle,
                       ledger->observations.end(), by_hash);
    ledger->observations.erase(
        std::unique(ledger->observations.begin(), ledger->observations.end(),
                    [](const auto& a, const auto& b) { return a.first == b.first; }),
        ledger->observations.end());
    ledger->Index();
  }
  std::vector<std::pair<uint64_t, Eigen::Vector3d>> new_images;
  for (const auto& [hash, centre] : in.images) {
    if (!ledger->ImageCentre(hash)) new_images.push_back({hash, Apply(t, centre)});
  }
  ledger->images.insert(ledger->images.end(), new_images.begin(), new_images.end());
  std::stable_sort(ledger->images.begin(), ledger->images.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  ledger->images.erase(std::unique(ledger->images.begin(), ledger->images.end(),
                                   [](const auto& a, const auto& b) { return a.first == b.first; }),
                       ledger->images.end());
  return ledger->lines.size() != lines_before || !added.empty() || !new_images.empty() ||
         sketched || ledger->diagonal != diagonal_before;
}

}  // namespace linecloud
