#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-p6L: rays of a calibrated rig against 6 map lines (Speciale et al., CVPR
// 2019, Table 1; the generalized relative pose problem of Stewénius, Nistér,
// Oskarsson, Åström, "Solutions to minimal generalized relative pose
// problems", OMNIVIS 2005, with one side made of lines). Find R, t such that
// ray i (origin o_i, direction d_i, moment m_i = o_i × d_i, rig frame) meets
// the moved line (R v_i, R w_i + t × R v_i):
//     d_iᵀ (R w_i + t × R v_i) + m_iᵀ R v_i = 0,   i = 1..6.
// Cayley form R̃ = (1 + |s|²) R: row_i(s) = [(R̃v_i × d_i)ᵀ, d_iᵀR̃w_i + m_iᵀR̃v_i]
// is quadratic in s and (t, 1) spans the null space of the 6 × 4 matrix of
// rows, so its 15 4 × 4 minors vanish; each is (1 + |s|²) times a sextic.
// The 15 sextics have 64 solutions, found from a 64 × 64 action matrix
// (multiplication by s_x) built by a 99 × 163 elimination template
// (tools/p6l_template.py → p6l_template.h). Real solutions are polished by
// Newton steps on the six equations in (R, t) and kept when every ray meets
// its line in front of its camera (camera-side cheirality only: no sign is
// imposed along a line). rig_from_world; up to 64 solutions (typically 2–6).
int m_p6l(std::span<const Eigen::Vector3d> origins, std::span<const Eigen::Vector3d> directions,
          std::span<const PluckerLine> lines, std::vector<Rigid3d>* out);

// p6L: one camera (every ray through the origin, m_i = 0), cam_from_world.
int p6l(std::span<const Eigen::Vector3d> bearings, std::span<const PluckerLine> lines,
        std::vector<Rigid3d>* out);

}  // namespace linecloud
