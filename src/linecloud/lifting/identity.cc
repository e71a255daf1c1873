#include "linecloud/lifting/identity.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>
#include <random>

#include <Eigen/Geometry>

#include "linecloud/geometry/line_grid.h"
#include "linecloud/lifting/lifting.h"
#include "linecloud/lifting/line_cloud.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

Eigen::Vector3d Apply(const Sim3d& t, const Eigen::Vector3d& x) { return t * x; }

// Similarity ledger_from_model through the shared images' centres: RANSAC
// over triples (fixed seed) of Eigen's umeyama, refitted on the inliers.
Sim3d AlignThroughImages(const std::vector<Eigen::Vector3d>& model,
                         const std::vector<Eigen::Vector3d>& ledger) {
  const size_t n = model.size();
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& c : ledger) mean += c;
  mean /= static_cast<double>(n);
  double spread = 0;
  for (const auto& c : ledger) spread += (c - mean).squaredNorm();
  spread = std::sqrt(spread / static_cast<double>(n));
  const double tolerance = 0.02 * spread;
  const auto fit = [&](const std::vector<size_t>& idx) {
    Eigen::Matrix3Xd src(3, idx.size()), dst(3, idx.size());
    for (size_t k = 0; k < idx.size(); ++k) {
      src.col(k) = model[idx[k]];
      dst.col(k) = ledger[idx[k]];
    }
    const Eigen::Matrix4d m = Eigen::umeyama(src, dst, true);
    const Eigen::Matrix3d sr = m.topLeftCorner<3, 3>();
    const double s = std::cbrt(sr.determinant());
    Sim3d t;
    t.scale = s;
    t.rotation = Eigen::Quaterniond(sr / s).normalized();
    t.translation = m.topRightCorner<3, 1>();
    return t;
  };
  const auto inliers = [&](const Sim3d& t) {
    std::vector<size_t> in;
    for (size_t k = 0; k < n; ++k) {
      if ((Apply(t, model[k]) - ledger[k]).norm() <= tolerance) in.push_back(k);
    }
    return in;
  };
  // The same gauge (a re-triangulation, an update): exactly the identity, so
  // that a re-lift gives bit-identical lines.
  double worst = 0;
  for (size_t k = 0; k < n; ++k) worst = std::max(worst, (model[k] - ledger[k]).norm());
  if (worst <= 1e-9 * std::max(spread, 1e-300)) return Sim3d();
  std::vector<size_t> all(n);
  for (size_t k = 0; k < n; ++k) all[k] = k;
  Sim3d best = fit(all);
  std::vector<size_t> best_in = inliers(best);
  std::mt19937_64 rng(7);
  for (int iter = 0; iter < 300 && best_in.size() < n; ++iter) {
    std::vector<size_t> sample;
    std::sample(all.begin(), all.end(), std::back_inserter(sample), 3, rng);
    const Sim3d t = fit(sample);
    if (!(t.scale > 0) || !t.translation.allFinite()) continue;
    std::vector<size_t> in = inliers(t);
    if (in.size() > best_in.size()) {
      best = t;
      best_in = std::move(in);
    }
  }
  if (best_in.size() >= 3) best = fit(best_in);
  return best;
}

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

IdentityResult AssignDirections(const LiftingKey& key, const IdentityInput& in,
                                const ReleaseLedger& ledger, const IdentityOptions& o) {
  o.Check();
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
  const bool compact_key = key.directions() == DirectionSet::kCompact256;
  IdentityResult r;
  r.directions.resize(n);
  r.compact.assign(n, 0);
  r.ledger_line.assign(n, -1);
  r.keep.assign(n, 1);
  r.anchors.assign(in.points.begin(), in.points.end());
  // Fresh keyed directions: what every point gets without a released identity.
  std::vector<Eigen::Vector3d> fresh(n);
  std::vector<uint8_t> fresh_compact(n);
  KeyedDirections(key, in.ids, fresh.data(), fresh_compact.data());
  if (compact_key) {
    for (size_t i = 0; i < n; ++i) fresh[i] = CompactDirections()[fresh_compact[i]];
  }
  const double diagonal = RobustBox(in.points, 0.005, 0.0).diagonal().norm();
  r.same_place_distance = std::max(o.same_place * diagonal, 1e-12);

  // 1. Alignment and observations.
  if (!ledger.empty()) {
    std::vector<Eigen::Vector3d> model_c, ledger_c;
    for (const auto& [hash, centre] : in.images) {
      // An image may be listed under two hashes (its name, its features):
      // once per image.
      if (!model_c.empty() && model_c.back() == centre) continue;
      if (const Eigen::Vector3d* c = ledger.ImageCentre(hash)) {
        model_c.push_back(centre);
        ledger_c.push_back(*c);
      }
    }
    r.shared_images = model_c.size();
    if (model_c.size() >= 3) r.ledger_from_model = AlignThroughImages(model_c, ledger_c);
  }
  const Eigen::Matrix3d rotation = r.ledger_from_model.rotation.toRotationMatrix();
  const Sim3d model_from_ledger = r.ledger_from_model.Inverse();
  const double snap = std::min(o.same_place, kMaxSnap) * diagonal;
  // Point i's line becomes released line `l` itself when it passes within
  // `snap` of the point (not exactly through it: then the point stays).
  const auto snap_to = [&](size_t i, const PluckerLine& l) {
    const Eigen::Vector3d p =
        Apply(model_from_ledger, l.ClosestPointTo(Apply(r.ledger_from_model, in.points[i])));
    const double d = (p - in.points[i]).norm();
    if (d <= snap && d > 1e-12 * std::max(diagonal, 1e-300)) {
      r.anchors[i] = p;
      ++r.on_released_line;
    }
  };
  const bool rotated = (rotation - Eigen::Matrix3d::Identity()).norm() > 1e-9;
  std::vector<double> distances;
  std::vector<std::pair<int64_t, int>> votes;
  for (size_t i = 0; i < n && !ledger.empty(); ++i) {
    votes.clear();
    for (uint32_t k = in.observation_start[i]; k < in.observation_start[i + 1]; ++k) {
      const int64_t line = ledger.LineOfObservation(in.observations[k]);
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
        *std::max_element(votes.begin(), votes.end(), [](const auto& a, const auto& b) {
          return a.second < b.second || (a.second == b.second && a.first > b.first);
        });
    const PluckerLine& line = ledger.lines[best.first];
    bool conflict = false;
    for (const auto& v : votes) conflict |= !SameDirection(ledger.lines[v.first].v, line.v);
    if (conflict) {
      r.keep[i] = 0;
      ++r.left_out;
      continue;
    }
    r.ledger_line[i] = best.first;
    r.directions[i] = rotation.transpose() * line.v;
    r.compact[i] = ledger.compact[best.first];
    snap_to(i, line);
    ++r.from_observations;
    distances.push_back(line.DistanceTo(Apply(r.ledger_from_model, in.points[i])) /
                        (r.ledger_from_model.scale * std::max(diagonal, 1e-300)));
  }
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
  if (!distances.empty()) {
    std::nth_element(distances.begin(), distances.begin() + distances.size() / 2, distances.end());
    r.misalignment = distances[distances.size() / 2];
    if (!(r.misalignment <= o.max_misalignment)) {
      Fail(
          "this version of the model shares {} observations with its released version but "
          "cannot be aligned with it ({} shared images; after alignment its points lie {:.2g} % "
          "of the scene diagonal from their released lines, median): lifting it would give "
          "those points crossing lines. Align it to the released version first (colmap "
          "model_aligner) and lift it from the released version's database; a key of its own "
          "(--key-file NEW --force) only if it is another place, never for the same scene",
          r.from_observations, r.shared_images, 100 * r.misalignment);
    }
    if (compact_key && rotated) {
      Fail(
          "this version of the model has another gauge than its released version, and a "
          "compact256 key's 256 directions cannot follow the rotation between them: align it "
          "to the released model first (colmap model_aligner), or lift with a sphere key");
    }
  }

  // 2. Same place: points of this version, then released lines. Points are
  // sorted into cells of side 2 eps: the eps-ball of a point then meets at
  // most the 8 cells on its side of each half cell.
  const double eps = r.same_place_distance;
  const double side = 2 * eps;
  Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  for (const auto& x : in.points) low = low.cwiseMin(x);
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
    const Eigen::Vector3d& x = in.points[i];
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
  std::vector<uint8_t> assigned(n, 0);
  for (size_t i = 0; i < n; ++i) assigned[i] = r.ledger_line[i] >= 0;
  std::unique_ptr<LineGrid> released;
  std::vector<uint32_t> near;
  // In cell order (neighbours are near in memory); a deterministic order.
  for (const auto& [cell_key, point] : cells) {
    const size_t i = point;
    if (assigned[i] || !r.keep[i]) continue;
    if (o.legacy_release) {
      r.directions[i] = fresh[i];
      r.compact[i] = fresh_compact[i];
      assigned[i] = 1;
      ++r.fresh;
      continue;
    }
    const Eigen::Vector3d& x = in.points[i];
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
        // Only from a point with a direction of its own (no chains: a bundle
        // of parallel lines stays within `same_place` of its seed).
        if (j == i || assigned[j] != 1 || !r.keep[j]) continue;
        const double d = (in.points[j] - x).norm();
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
    if (!ledger.empty() && !(compact_key && rotated)) {
      if (!released) {
        // The released lines near this version's points (in the ledger frame).
        std::vector<Eigen::Vector3d> in_ledger(n);
        for (size_t k = 0; k < n; ++k) in_ledger[k] = Apply(r.ledger_from_model, in.points[k]);
        released = std::make_unique<LineGrid>(ledger.lines, RobustBox(in_ledger, 0.005, 0.05),
                                              eps * r.ledger_from_model.scale);
      }
      const Eigen::Vector3d x = Apply(r.ledger_from_model, in.points[i]);
      released->LinesNear(x, &near);
      int64_t best_line = -1;
      for (const uint32_t l : near) {
        const double d = ledger.lines[l].DistanceTo(x);
        if (d < best_d) best_d = d, best_line = l;
      }
      if (best_line >= 0) {
        r.directions[i] = rotation.transpose() * ledger.lines[best_line].v;
        r.compact[i] = ledger.compact[best_line];
        snap_to(i, ledger.lines[best_line]);
        r.ledger_line[i] = best_line;
        assigned[i] = 1;
        ++r.from_released_place;
        continue;
      }
    }
    r.directions[i] = fresh[i];
    r.compact[i] = fresh_compact[i];
    assigned[i] = 1;
    ++r.fresh;
  }
  return r;
}

bool RecordRelease(const IdentityInput& in, const IdentityResult& r,
                   std::span<const size_t> released, ReleaseLedger* ledger) {
  const size_t lines_before = ledger->lines.size();
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
      line = static_cast<int64_t>(ledger->lines.size()) - 1;
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
  return ledger->lines.size() != lines_before || !added.empty() || !new_images.empty();
}

}  // namespace linecloud
