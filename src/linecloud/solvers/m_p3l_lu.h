#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P3L+l+u: local 3D points (unknown scale) against 3 map lines, known
// gravity (Camposeco, Cohen, Pollefeys, Sattler, "Hybrid camera pose
// estimation", CVPR 2018, the upright generalized pose-and-scale case; here
// as in Speciale et al., CVPR 2019, with map and query swapped).
// Find s > 0, R = R_y(θ), t with
//     X̃_i = s R (v_i × w_i + α_i v_i) + t,   i = 1, 2, 3.
// world_from_local = (s', R', t') puts s' R' X̃_i + t' on line i:
//     K(X̃_i) y + t' = a_i + λ_i v_i,   y = (s' cos θ, s' sin θ, s'),
// linear in (y, t', λ) (the 6 × 6 system of the projections onto u ⟂ v_i,
// with s' treated as its own unknown). Differences to line 0 remove t'; their
// components along v_i × v_0 and the two values of λ_0 they give leave a
// 3 × 3 system in y (Cramer's rule), then λ_0 and t'. One solution.
// local_from_world.
int m_p3l_lu(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
             std::vector<Sim3d>* out);

}  // namespace linecloud
