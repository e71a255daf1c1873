#pragma once

#include <span>
#include <vector>

#include <Eigen/Core>

#include "linecloud/geometry/plucker.h"
#include "linecloud/geometry/rigid3.h"

namespace linecloud {

// m-P2L+l+u+s: local 3D points (metric) against 2 map lines, known gravity
// (the problem of Sweeney et al., ISMAR 2015, with map and query swapped as in
// Speciale et al., CVPR 2019, Table 1). Find R = R_y(θ), t with
//     X̃_i = R (v_i × w_i + α_i v_i) + t,   i = 1, 2.
// Equivalently world_from_local = (Rᵀ, −Rᵀt) moves X̃_i onto line i: the
// generalized upright 2-point problem with the lines as rays (m_p2p_u).
// Up to 2 solutions, local_from_world (= rig_from_world).
int m_p2l_lus(std::span<const PluckerLine> lines, std::span<const Eigen::Vector3d> points_local,
              std::vector<Rigid3d>* out);

}  // namespace linecloud
