// Keyed, reproducible sparsification of a map before lifting: the paper's
// defence against the density of a line cloud revealing the scene (Speciale et
// al., CVPR 2019, supplementary; Chelani et al., CVPR 2021 measure it), and a
// spatially balanced variant of our own.
//
// Both keep a subset of the points and lift each kept point exactly as the
// full lifting would (same key, same line): a sparse map is a subset of the
// lines of the full one, so two maps of one model never hold two lines
// through one point.
//
//  - kUniform: point i is kept iff u_i ≥ drop, u_i ∈ [0, 1) a keyed
//    pseudo-random number of its id. Nested: a sparser map is a subset of a
//    denser one under the same key.
//  - kBalanced: the attack feeds on local density (the lines of a point's
//    near neighbours vote for it), and SfM points cluster where the texture
//    is. This mode caps the density instead of thinning everywhere alike: a
//    grid of cubic cells (keyed offset) keeps in each cell only the point of
//    smallest u_i; the cell size is the one (by bisection) for which the kept
//    share is 1 − drop. Clusters lose most of their points, sparse regions
//    few, so the kept map covers the scene as before for localization.
#pragma once

#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "linecloud/lifting/key.h"

namespace linecloud {

enum class SparsifyMode : uint8_t { kUniform = 0, kBalanced = 1 };

std::string_view SparsifyModeName(SparsifyMode mode);
// "uniform" or "balanced"; throws Error naming `source` otherwise.
SparsifyMode SparsifyModeFromName(std::string_view name, std::string_view source);

// The indices (into ids/points, increasing) of the points kept when a share
// `drop` ∈ [0, 1) is dropped. drop = 0 keeps all. Throws Error on a drop
// outside [0, 1) or mismatched sizes.
std::vector<size_t> SparsifyPoints(const LiftingKey& key, std::span<const uint64_t> ids,
                                   std::span<const Eigen::Vector3d> points, double drop,
                                   SparsifyMode mode);

}  // namespace linecloud
