#include "linecloud/lifting/sparsify.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "linecloud/lifting/lifting.h"
#include "linecloud/util/error.h"

namespace linecloud {
namespace {

constexpr char kSparsifyPurpose[] = "linecloud/lift/sparsify/v1";

// Keyed uniforms u_i ∈ [0, 1) of the ids: their line ids under a key derived
// for this purpose (a block cipher output, i.e. pseudo-random per id).
std::vector<double> KeyedUniforms(const LiftingKey& key, std::span<const uint64_t> ids) {
  const LiftingKey sub(key.DeriveSubkey(kSparsifyPurpose), key.directions());
  const std::vector<uint64_t> bits = LineIdsOfPoints(sub, ids);
  std::vector<double> u(ids.size());
  for (size_t i = 0; i < ids.size(); ++i) u[i] = static_cast<double>(bits[i] >> 11) * 0x1.0p-53;
  return u;
}

struct CellHash {
  size_t operator()(const Eigen::Vector3i& c) const {
    return (static_cast<size_t>(c.x()) * 73856093u) ^ (static_cast<size_t>(c.y()) * 19349663u) ^
           (static_cast<size_t>(c.z()) * 83492791u);
  }
};
struct CellEqual {
  bool operator()(const Eigen::Vector3i& a, const Eigen::Vector3i& b) const { return a == b; }
};

// One point per cell of size `cell` (the smallest u), cells offset by `offset`.
std::vector<size_t> OnePerCell(std::span<const Eigen::Vector3d> points,
                               const std::vector<double>& u, double cell,
                               const Eigen::Vector3d& offset) {
  std::unordered_map<Eigen::Vector3i, size_t, CellHash, CellEqual> best;
  best.reserve(points.size());
  for (size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3d c = ((points[i] - offset) / cell).array().floor();
    const Eigen::Vector3i key(static_cast<int>(c.x()), static_cast<int>(c.y()),
                              static_cast<int>(c.z()));
    const auto [it, inserted] = best.emplace(key, i);
    if (!inserted && u[i] < u[it->second]) it->second = i;
  }
  std::vector<size_t> kept;
  kept.reserve(best.size());
  for (const auto& [c, i] : best) kept.push_back(i);
  std::sort(kept.begin(), kept.end());
  return kept;
}

}  // namespace

std::string_view SparsifyModeName(SparsifyMode mode) {
  return mode == SparsifyMode::kBalanced ? "balanced" : "uniform";
}

SparsifyMode SparsifyModeFromName(std::string_view name, std::string_view source) {
  if (name == "uniform") return SparsifyMode::kUniform;
  if (name == "balanced") return SparsifyMode::kBalanced;
  Fail("{}: '{}' is not a sparsification mode (uniform or balanced)", source, name);
}

std::vector<size_t> SparsifyPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                   std::span<const Eigen::Vector3d> points, double drop,
                                   SparsifyMode mode) {
  if (!(drop >= 0 && drop < 1)) Fail("--sparsify: {} is not a share in [0, 1)", drop);
  if (ids.size() != points.size())
    Fail("sparsify: {} ids but {} points", ids.size(), points.size());
  std::vector<size_t> all(ids.size());
  for (size_t i = 0; i < all.size(); ++i) all[i] = i;
  if (drop == 0 || ids.empty()) return all;
  EnsureSodiumInitialized();
  const std::vector<double> u = KeyedUniforms(key, ids);
  if (mode == SparsifyMode::kUniform) {
    std::vector<size_t> kept;
    for (size_t i = 0; i < ids.size(); ++i) {
      if (u[i] >= drop) kept.push_back(i);
    }
    return kept;
  }
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) Fail("sparsify: a point has non-finite coordinates");
  }
  // Keyed grid offset in [0, 1) cells (from three more keyed uniforms).
  const std::array<uint64_t, 3> offset_ids = {~0ull, ~1ull, ~2ull};
  const std::vector<double> o = KeyedUniforms(key, offset_ids);
  Eigen::Vector3d lo = points[0], hi = points[0];
  for (const auto& p : points) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const size_t target = static_cast<size_t>(std::llround((1 - drop) * ids.size()));
  // Kept count falls as the cell grows: bisect log(cell) for the target.
  double small = 1e-9 * std::max(1.0, (hi - lo).norm()), large = 2 * (hi - lo).norm() + 1;
  std::vector<size_t> kept;
  for (int iteration = 0; iteration < 60; ++iteration) {
    const double cell = std::sqrt(small * large);
    kept = OnePerCell(points, u, cell, lo - cell * Eigen::Vector3d(o[0], o[1], o[2]));
    if (kept.size() == target) break;
    (kept.size() > target ? small : large) = cell;
    if (large / small < 1 + 1e-9) break;
  }
  return kept;
}

}  // namespace linecloud
