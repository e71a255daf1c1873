// Keyed, permanent lifting of points to lines (Speciale et al., "Privacy
// Preserving Image-Based Localization", CVPR 2019, Sec. 3.1).
//
// Each point X with id i becomes the line through X with direction v_i, where
// v_i is drawn uniformly on the unit sphere by a keyed pseudo-random function
// of (key, i): ChaCha20 (libsodium) under a subkey derived from the map key,
// block counter i, gives 64 pseudo-random bytes; two 53-bit uniforms u1, u2
// map to v = (sqrt(1 − z²) cos φ, sqrt(1 − z²) sin φ, z) with z = 1 − 2 u1 and
// φ = 2π u2 (Archimedes: z uniform ⇒ v uniform on S²). Byte 16 picks the
// compact direction, which is *the* direction of a kCompact256 key.
//
// One point, one line: the line of point i depends only on (key, i, X_i) —
// never on the encoding, the options, the output or the run. Under a sphere
// key only the full encoding exists (the compact encoding is refused); under
// a compact256 key both encodings store the same float32-rounded line.
//
// Line ids: a line carries not its point's id but a keyed permutation of it
// (the 64-bit block cipher Speck64/128 under a subkey of the map key), and a cloud is stored sorted
// by line id, so neither ids nor order say anything about which points are neighbours (COLMAP
// numbers points in triangulation order). The key's owner maps point ids to line ids and back
// (LineIdsOfPoints, PointIdOfLine).
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/key.h"
#include "linecloud/lifting/line_cloud.h"

namespace linecloud {

struct LiftingOptions {
  LineEncoding encoding = LineEncoding::kPlucker;
};

// The keyed direction of point `ids[k]` into `directions[k]` (uniform on S²),
// and its compact direction index into `compact_indices[k]` when non-null.
void KeyedDirections(const LiftingKey& key, std::span<const uint64_t> ids,
                     Eigen::Vector3d* directions, uint8_t* compact_indices);

// The line id of point id `point_id` under `key`, and back.
uint64_t LineIdOfPoint(const LiftingKey& key, uint64_t point_id);
uint64_t PointIdOfLine(const LiftingKey& key, uint64_t line_id);
// Many at once: the key's subkey and round keys are derived once.
std::vector<uint64_t> LineIdsOfPoints(const LiftingKey& key, std::span<const uint64_t> point_ids);
std::vector<uint64_t> PointIdsOfLines(const LiftingKey& key, std::span<const uint64_t> line_ids);
// The block cipher itself (exposed for its published test vector).
uint64_t Speck64Encrypt(const std::array<uint32_t, 4>& key, uint64_t block);

// Lifts points (ids[k], points[k]) to a line cloud whose ids are the line ids
// of `ids`, in increasing line-id order. Throws Error on non-finite points,
// repeated ids, mismatched sizes, or the compact encoding under a sphere key.
LineCloud LiftPoints(std::span<const uint64_t> ids, std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options);
// The same with the points' directions given (identity.h: a direction that
// follows a point across versions of its model): unit `directions` for a
// sphere key, `compact_indices` for a compact256 key (one per point each).
LineCloud LiftPoints(std::span<const uint64_t> ids, std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options,
                     std::span<const Eigen::Vector3d> directions,
                     std::span<const uint8_t> compact_indices);

}  // namespace linecloud
