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
// world_from_local = (s', R', t') puts s' R' X̃_i + t' on line i; projecting
// onto u ⟂ v_i gives 6 equations linear in (s' cos θ, s' sin θ, s', t'):
// a 6 × 6 linear system, one solution. local_from_world.
int m_p3l_lu(std::span<const PluckerLine> lines,
             std::span<const Eigen::Vector3d> points_local, std::vector<Sim3d>* out);

}  // namespace linecloud
