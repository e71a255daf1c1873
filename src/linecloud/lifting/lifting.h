// Keyed, permanent lifting of points to lines (Speciale et al., "Privacy
// Preserving Image-Based Localization", CVPR 2019, Sec. 3.1).
//
// Each point X with id i becomes the line through X with direction v_i, where
// v_i is drawn uniformly on the unit sphere by a keyed pseudo-random function
// of (key, i): ChaCha20 (libsodium) under a subkey derived from the map key,
// block counter i, gives 64 pseudo-random bytes; two 53-bit uniforms u1, u2
// map to v = (sqrt(1 − z²) cos φ, sqrt(1 − z²) sin φ, z) with z = 1 − 2 u1 and
// φ = 2π u2 (Archimedes: z uniform ⇒ v uniform on S²). Byte 16 picks the
// compact direction. The same (key, id) always gives the same line, so a map
// re-lifted with its key reveals nothing new.
#pragma once

#include <cstdint>
#include <span>

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

// Lifts points (ids[k], points[k]) to a line cloud. Throws Error on
// non-finite points, repeated ids or mismatched sizes.
LineCloud LiftPoints(std::span<const uint64_t> ids,
                     std::span<const Eigen::Vector3d> points,
                     const LiftingKey& key, const LiftingOptions& options);

}  // namespace linecloud
